"""Static int8 quantisation (QDQ) of an fp32 TinyDet / YOLOv8 ONNX model.

Calibration: views of training frames as the detector sees them at run time,
alternately a whole frame letterboxed into the input and a native-resolution
tile (MinMax, per-channel int8 weights in 7 bits, uint8 activations). Everything up to the heads' last
convolutions is quantised (Conv + ReLU fuse into one int8 convolution, Add,
Concat, Resize, ...); the box decoding after the heads (Softplus / Sigmoid and
the arithmetic that turns distances into boxes) stays float, so box
coordinates keep full precision.

Usage: python quantize.py --fp32 model.onnx --out model-int8.onnx --data DIR
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import onnx
from onnxruntime.quantization import CalibrationDataReader, CalibrationMethod, QuantFormat, QuantType, quantize_static
from onnxruntime.quantization.shape_inference import quant_pre_process

import data

# 7-bit weights (onnxruntime's reduce_range). With full 8-bit weights, tract and
# ONNX Runtime gave scores up to 1.3e-2 apart on this model at 800x448 (likely
# int8 products summed in a saturating 16-bit step on one side, the usual
# reason for reduce_range); with 7 bits both give identical scores on
# whole frames, and held-out mAP50 did not drop (models/README.md).
REDUCE_RANGE = True


class FrameReader(CalibrationDataReader):
    def __init__(self, frames, size: tuple[int, int], input_name: str):
        self.frames = iter(frames)
        self.size = size
        self.input_name = input_name

    def get_next(self):
        img = next(self.frames, None)
        if img is None:
            return None
        lb, *_ = data.letterbox(img, self.size)
        return {self.input_name: data.to_tensor_chw(lb)[None]}


def calibration_frames(args, size: tuple[int, int]):
    """Every k-th training frame; odd ones cropped to an input-sized tile (H x W) around their first box."""
    th, tw = size
    samples = data.load_dataset(Path(args.data), "train")
    step = max(1, len(samples) // args.count)
    for i, (path, boxes, _) in enumerate(samples[::step][: args.count]):
        img = data.read_image(path)
        if i % 2 and len(boxes):
            h, w = img.shape[:2]
            cx, cy = (boxes[0, 0] + boxes[0, 2]) / 2, (boxes[0, 1] + boxes[0, 3]) / 2
            x0 = int(min(max(0, cx - tw / 2), max(0, w - tw)))
            y0 = int(min(max(0, cy - th / 2), max(0, h - th)))
            img = np.ascontiguousarray(img[y0 : y0 + th, x0 : x0 + tw])
        yield img


def decode_nodes(model: onnx.ModelProto) -> list[str]:
    """Names of the heads' last convolutions and every node after them (the box decoding).

    Keeping the heads' final 1x1 convolutions in float matters for more than
    precision: a uint8 logit has coarse steps (about 0.014 in score), and the
    two backends may round the same value to neighbouring steps. With float
    logits tract and ONNX Runtime agree to well under 1e-3.
    """
    consumers: dict[str, list] = {}
    producer: dict[str, onnx.NodeProto] = {}
    for n in model.graph.node:
        for i in n.input:
            consumers.setdefault(i, []).append(n)
        for o in n.output:
            producer[o] = n
    todo = [n for n in model.graph.node if n.op_type in ("Softplus", "Sigmoid")]
    todo += [producer[n.input[0]] for n in list(todo) if n.input[0] in producer and producer[n.input[0]].op_type == "Conv"]
    seen: set[str] = set()
    while todo:
        n = todo.pop()
        if n.name in seen:
            continue
        seen.add(n.name)
        for o in n.output:
            todo.extend(consumers.get(o, []))
    return sorted(seen)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fp32", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--data", required=True, help="training sequences (COCO-style JSON + images)")
    ap.add_argument("--count", type=int, default=128)
    ap.add_argument(
        "--float-prefix",
        action="append",
        default=[],
        help="also keep nodes whose name starts with this in float (repeatable), e.g. /heads.0/cls/",
    )
    args = ap.parse_args()
    model = onnx.load(args.fp32)
    inp = model.graph.input[0]
    dims = inp.type.tensor_type.shape.dim
    size = (dims[2].dim_value, dims[3].dim_value)
    with tempfile.TemporaryDirectory() as tmp:
        pre = str(Path(tmp) / "pre.onnx")
        quant_pre_process(args.fp32, pre)
        pre_model = onnx.load(pre)
        exclude = decode_nodes(pre_model)
        exclude += [n.name for n in pre_model.graph.node if any(n.name.startswith(p) for p in args.float_prefix)]
        exclude = sorted(set(exclude))
        quantize_static(
            pre,
            args.out,
            FrameReader(calibration_frames(args, size), size, inp.name),
            quant_format=QuantFormat.QDQ,
            nodes_to_exclude=exclude,
            per_channel=True,
            reduce_range=REDUCE_RANGE,
            weight_type=QuantType.QInt8,
            activation_type=QuantType.QUInt8,
            calibrate_method=CalibrationMethod.MinMax,
        )
    # Keep the fp32 model's metadata (class names, input size) on the int8 one.
    q = onnx.load(args.out)
    del q.metadata_props[:]
    for p in model.metadata_props:
        n = q.metadata_props.add()
        n.key, n.value = p.key, p.value
    n = q.metadata_props.add()
    n.key, n.value = "quantization", "int8 static QDQ (onnxruntime.quantization, MinMax, per-channel)"
    onnx.save(q, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
