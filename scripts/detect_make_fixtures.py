#!/usr/bin/env python3
"""Regenerates tests/fixtures/detect/ (run with train/.venv's python).

- sim_heldout_a.jpg, sim_heldout_b.jpg, sim_heldout_c.jpg + gt.json: held-out frames rendered by
  train/run.sh (train/data/sim/heldout, seeds 100001/100002, never trained
  on), copied byte for byte, with their boxes of all five SeaDronesSee
  classes (COCO, category 1 swimmer, 2 boat, 3 jetski, 4 life-saving
  appliance, 5 buoy). Chosen automatically: frame a shows the most classes at
  sizes the shipped model resolves on whole frames (longer side >= 10 px),
  frame b the most such swimmers among the other sequences, frame c the
  most boats and jetskis among the rest. gt.json names the
  sequence and frame each was copied from.
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

import numpy as np
import onnx
from onnx import TensorProto, helper
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "train"))
import data  # noqa: E402
from classes import CLASS_NAMES  # noqa: E402

OUT = ROOT / "tests" / "fixtures" / "detect"
HELDOUT = ROOT / "train" / "data" / "sim" / "heldout"
MIN_SIDE = 10.0


def choose():
    """[(name, source path, boxes, classes)] for frames a and b (see the module doc)."""
    best_a = None
    for seq in sorted(p for p in HELDOUT.iterdir() if p.is_dir()):
        for path, boxes, classes in data.load_coco_dir(seq):
            sides = np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]) if len(boxes) else np.zeros(0)
            big = sides >= MIN_SIDE
            score_a = (len(set(classes[big].tolist())), int(big.sum()))
            if best_a is None or score_a > best_a[0]:
                best_a = (score_a, (seq.name, path, boxes, classes))
    if best_a is None:
        raise SystemExit(f"{HELDOUT} has no frames: run train/run.sh first (it renders the held-out set)")
    # Frame b from another sequence than a, if any has swimmers.
    best_b = None
    for seq in sorted(p for p in HELDOUT.iterdir() if p.is_dir() and p.name != best_a[1][0]):
        for path, boxes, classes in data.load_coco_dir(seq):
            sides = np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]) if len(boxes) else np.zeros(0)
            score_b = int(((sides >= MIN_SIDE) & (classes == 0)).sum())
            if best_b is None or score_b > best_b[0]:
                best_b = (score_b, (seq.name, path, boxes, classes))
    # Frame c: the most boats and jetskis, from a third sequence.
    best_c = None
    used = {best_a[1][0], best_b[1][0]}
    for seq in sorted(p for p in HELDOUT.iterdir() if p.is_dir() and p.name not in used):
        for path, boxes, classes in data.load_coco_dir(seq):
            sides = np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]) if len(boxes) else np.zeros(0)
            big = sides >= MIN_SIDE
            score_c = (int((big & ((classes == 1) | (classes == 2))).sum()), len(set(classes[big].tolist())))
            if best_c is None or score_c > best_c[0]:
                best_c = (score_c, (seq.name, path, boxes, classes))
    return [("sim_heldout_a.jpg", *best_a[1]), ("sim_heldout_b.jpg", *best_b[1]), ("sim_heldout_c.jpg", *best_c[1])]


def frames():
    images, anns = [], []
    for i, (name, seq, src, boxes, classes) in enumerate(choose(), start=1):
        shutil.copyfile(src, OUT / name)
        w, h = Image.open(src).size
        images.append({"id": i, "file_name": name, "width": w, "height": h,
                       "source": {"sequence": seq, "frame": src.name, "split": "heldout"}})
        for b, c in zip(boxes, classes):
            x1, y1, x2, y2 = (float(v) for v in b)
            anns.append({"id": len(anns) + 1, "image_id": i, "category_id": int(c) + 1,
                         "bbox": [x1, y1, x2 - x1, y2 - y1], "area": (x2 - x1) * (y2 - y1), "iscrowd": 0})
        print(f"{name}: {seq}/{src.name}, classes {sorted({CLASS_NAMES[int(c)] for c in classes})}, {len(boxes)} boxes")
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
