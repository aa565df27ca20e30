#!/usr/bin/env python3
"""Writes a copy of a detector laid out as an Ultralytics YOLOv8 / YOLO11 ONNX export.

The copy has the same weights and the same graph as the source model (the shipped
models/mgmot-det-fp32.onnx by default), but its classes come in another order: one Gather
on axis 1 appended to the graph permutes the class rows of `output0` (the four box rows
stay first), and the `names` metadata lists the classes in that new order. The metadata is
replaced by the keys an Ultralytics export writes (`description`, `author` 'Ultralytics',
`date`, `version`, `license`, `docs`, `stride`, `task`, `batch`, `imgsz`, `names` as a
Python dict literal, `args`, `channels`), every value a `str()` of a Python value as
Ultralytics writes it. Input `images` and output `output0` keep their names and shapes.

So a detector that maps class NAMES to SeaDronesSee category ids reports the same
categories for both files on the same image; one that used the class index would not.

The default order: for SeaDronesSee's five classes boat, swimmer, buoy,
life_saving_appliances, jetski; for any other set of classes the source's order reversed
(for the two-class swimmer/boat model: boat, swimmer). `--order` names another order;
`--rename OLD=NEW` renames a class after the permutation (e.g. `--rename boat=kayak` for a
model with a class that is none of SeaDronesSee's).

Needs only `onnx` and numpy (scripts/requirements-test.txt); no torch, no ultralytics.

Usage:
    .venv/bin/python3 scripts/detect_make_ultralytics.py --out /tmp/yolo.onnx
        [--model models/mgmot-det-fp32.onnx] [--order boat,swimmer] [--rename boat=kayak]

Prints the new `names` on stdout.
"""

import argparse
import ast
import datetime
import sys
from pathlib import Path

import numpy as np
import onnx
from onnx import helper, numpy_helper

ROOT = Path(__file__).resolve().parent.parent
SEADRONESSEE = ["swimmer", "boat", "jetski", "life_saving_appliances", "buoy"]
FIVE_CLASS_ORDER = ["boat", "swimmer", "buoy", "life_saving_appliances", "jetski"]
OUTPUT = "output0"


def read_names(model):
    for prop in model.metadata_props:
        if prop.key == "names":
            value = ast.literal_eval(prop.value)
            if isinstance(value, dict):
                return [value[i] for i in range(len(value))]
            return list(value)
    raise SystemExit("the source model has no `names` metadata")


def read_meta(model, key, default):
    for prop in model.metadata_props:
        if prop.key == key:
            return prop.value
    return default


def default_order(names):
    if sorted(names) == sorted(SEADRONESSEE):
        return list(FIVE_CLASS_ORDER)
    return list(reversed(names))


def permute_output(graph, num_classes, perm):
    """Renames the node output `output0` and appends a Gather that writes `output0` with the
    class rows in the order `perm` (new class j = source class perm[j])."""
    inner = OUTPUT + "_source_order"
    producers = [n for n in graph.node if OUTPUT in n.output]
    if len(producers) != 1:
        raise SystemExit(f"expected one node writing `{OUTPUT}`, found {len(producers)}")
    node = producers[0]
    node.output[list(node.output).index(OUTPUT)] = inner
    for other in graph.node:
        for i, name in enumerate(other.input):
            if name == OUTPUT:
                other.input[i] = inner
    rows = [0, 1, 2, 3] + [4 + p for p in perm]
    assert len(rows) == 4 + num_classes
    indices = OUTPUT + "_class_rows"
    graph.initializer.append(numpy_helper.from_array(np.array(rows, dtype=np.int64), indices))
    graph.node.append(
        helper.make_node("Gather", [inner, indices], [OUTPUT], axis=1, name="ultralytics_class_order")
    )


def ultralytics_metadata(names, imgsz, stride):
    """The metadata an Ultralytics export writes, each value `str()` of its Python value."""
    meta = {
        "description": "Ultralytics YOLO11n model trained on seadronessee.yaml",
        "author": "Ultralytics",
        "date": datetime.datetime.now().isoformat(),
        "version": "8.3.40",
        "license": "AGPL-3.0 License (https://ultralytics.com/license)",
        "docs": "https://docs.ultralytics.com",
        "stride": stride,
        "task": "detect",
        "batch": 1,
        "imgsz": imgsz,
        "names": dict(enumerate(names)),
        "args": {"batch": 1, "half": False, "dynamic": False, "simplify": True, "opset": 17, "nms": False},
        "channels": 3,
    }
    return {k: str(v) for k, v in meta.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, default=ROOT / "models" / "mgmot-det-fp32.onnx")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--order", help="comma-separated class names, the new order")
    ap.add_argument("--rename", action="append", default=[], metavar="OLD=NEW")
    args = ap.parse_args()

    model = onnx.load(str(args.model))
    names = read_names(model)
    order = args.order.split(",") if args.order else default_order(names)
    if sorted(order) != sorted(names):
        raise SystemExit(f"--order {order} is not a permutation of the model's classes {names}")
    perm = [names.index(n) for n in order]
    if perm == list(range(len(names))) and len(names) > 1:
        raise SystemExit(f"the order {order} is the source's: nothing would be permuted")

    outputs = [o.name for o in model.graph.output]
    if outputs != [OUTPUT]:
        raise SystemExit(f"expected the one output `{OUTPUT}`, the model has {outputs}")
    permute_output(model.graph, len(names), perm)

    new_names = list(order)
    for rule in args.rename:
        old, sep, new = rule.partition("=")
        if not sep or old not in new_names:
            raise SystemExit(f"--rename {rule}: expected OLD=NEW with OLD one of {new_names}")
        new_names[new_names.index(old)] = new

    imgsz = ast.literal_eval(read_meta(model, "imgsz", "[448, 800]"))
    stride = int(read_meta(model, "stride", "32"))
    del model.metadata_props[:]
    for key, value in ultralytics_metadata(new_names, imgsz, stride).items():
        prop = model.metadata_props.add()
        prop.key, prop.value = key, value
    model.producer_name = "pytorch"

    onnx.checker.check_model(model)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(model, str(args.out))
    print(str(dict(enumerate(new_names))))


if __name__ == "__main__":
    sys.exit(main())
