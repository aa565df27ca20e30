#!/usr/bin/env python3
"""Regenerates tests/fixtures/detect/ (run with train/.venv's python).

- sea_<seed>.jpg + gt.json: held-out frames of train/data.py's procedural
  generator (seeds far from the training range) with their true boxes (COCO).
- bad_rank.onnx: a valid model whose input has rank 3 (must be rejected).
- bad_layout.onnx: a valid model with a (1, 7) output (unknown layout).
- corrupt.onnx: bytes that are not a protobuf model.

Usage: train/.venv/bin/python scripts/detect_make_fixtures.py
"""

import json
import sys
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "train"))
import data  # noqa: E402
from model import CLASS_NAMES  # noqa: E402

OUT = ROOT / "tests" / "fixtures" / "detect"
SEEDS = [2_000_003, 2_000_011]


def frames():
    images, anns = [], []
    for i, seed in enumerate(SEEDS, start=1):
        img, boxes, classes = data.procedural_frame(seed)
        name = f"sea_{seed}.jpg"
        Image.fromarray(img).save(OUT / name, quality=92)
        images.append({"id": i, "file_name": name, "width": img.shape[1], "height": img.shape[0]})
        for b, c in zip(boxes, classes):
            x1, y1, x2, y2 = (float(v) for v in b)
            anns.append({"id": len(anns) + 1, "image_id": i, "category_id": int(c) + 1,
                         "bbox": [x1, y1, x2 - x1, y2 - y1], "area": (x2 - x1) * (y2 - y1), "iscrowd": 0})
    cats = [{"id": k + 1, "name": n} for k, n in enumerate(CLASS_NAMES)]
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
