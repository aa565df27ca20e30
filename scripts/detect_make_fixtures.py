#!/usr/bin/env python3
"""Regenerates tests/fixtures/detect/ (run with train/.venv's python).

- sim_<sequence>_<frame>.jpg + gt.json: held-out frames rendered by
  train/run.sh (train/data/sim/heldout, seeds 100001/100002, never trained on),
  copied byte for byte, with their swimmer / boat boxes (COCO, category 1
  swimmer, 2 boat; jetskis count as boats like in training).
- bad_rank.onnx: a valid model whose input has rank 3 (must be rejected).
- bad_layout.onnx: a valid model with a (1, 7) output (unknown layout).
- corrupt.onnx: bytes that are not a protobuf model.

Usage: train/run.sh (renders the held-out set), then
       train/.venv/bin/python scripts/detect_make_fixtures.py
"""

import json
import shutil
import sys
from pathlib import Path

import onnx
from onnx import TensorProto, helper
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "train"))
import data  # noqa: E402
from model import CLASS_NAMES  # noqa: E402

OUT = ROOT / "tests" / "fixtures" / "detect"
HELDOUT = ROOT / "train" / "data" / "sim" / "heldout"
# (sequence, frame file): held-out frames with swimmers and a boat at sizes
# the shipped 800x448 model resolves on the whole frame.
FRAMES = [
    ("leave_and_return_s100002", "img1/000001.jpg"),
    ("boats_crossing_s100002", "img1/000631.jpg"),
]


def frames():
    images, anns = [], []
    for i, (seq, frame) in enumerate(FRAMES, start=1):
        src = HELDOUT / seq / frame
        if not src.is_file():
            raise SystemExit(f"{src} is missing: run train/run.sh first (it renders the held-out set)")
        name = f"sim_{seq}_{Path(frame).stem}.jpg"
        shutil.copyfile(src, OUT / name)
        w, h = Image.open(src).size
        images.append({"id": i, "file_name": name, "width": w, "height": h})
        samples = {p.resolve(): (b, c) for p, b, c in data.load_coco_dir(HELDOUT / seq)}
        boxes, classes = samples[src.resolve()]
        for b, c in zip(boxes, classes):
            x1, y1, x2, y2 = (float(v) for v in b)
            anns.append({"id": len(anns) + 1, "image_id": i, "category_id": int(c) + 1,
                         "bbox": [x1, y1, x2 - x1, y2 - y1], "area": (x2 - x1) * (y2 - y1), "iscrowd": 0})
    cats = [{"id": k + 1, "name": n} for k, n in enumerate(CLASS_NAMES)]
    for old in OUT.glob("*.jpg"):
        if old.name not in {im["file_name"] for im in images}:
            old.unlink()
    (OUT / "gt.json").write_text(json.dumps({"images": images, "annotations": anns, "categories": cats}, indent=1))


def tiny_model(path, in_shape, out_shape):
    """Identity-ish graph: ReduceMean over the input then Expand to the output shape."""
    x = helper.make_tensor_value_info("images", TensorProto.FLOAT, in_shape)
    y = helper.make_tensor_value_info("output0", TensorProto.FLOAT, out_shape)
    shape = helper.make_tensor("shape", TensorProto.INT64, [len(out_shape)], out_shape)
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["m"], keepdims=0),
        helper.make_node("Expand", ["m", "shape"], ["output0"]),
    ]
    g = helper.make_graph(nodes, "fixture", [x], [y], initializer=[shape])
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)])
    m.ir_version = 8
    onnx.checker.check_model(m)
    onnx.save(m, path)


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    frames()
    tiny_model(OUT / "bad_rank.onnx", [3, 64, 64], [1, 6, 84])
    tiny_model(OUT / "bad_layout.onnx", [1, 3, 64, 64], [1, 7])
    (OUT / "corrupt.onnx").write_bytes(b"\x08\x07this is not an onnx model\xff\xfe" * 4)
    print(f"wrote fixtures into {OUT}")


if __name__ == "__main__":
    main()
