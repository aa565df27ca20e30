"""Export a TinyDet checkpoint (or an untrained, seeded network) to ONNX.

The graph: input ``images`` float32 (1, 3, H, W) RGB in [0, 1], letterboxed;
output ``output0`` float32 (1, 4 + nc, N), the Ultralytics YOLOv8 layout.
Metadata keys follow Ultralytics (``names``, ``imgsz``, ``stride``, ``task``)
so that the Rust loader reads class names and input size the same way for
both kinds of model.

Usage: python export.py --ckpt ckpt.pt --out model.onnx [--size 448,800]
       python export.py --untrained --seed 0 --out model.onnx
"""

from __future__ import annotations

import argparse

import onnx
import torch

from model import CLASS_NAMES, TinyDet

OPSET = 17


def export(model: TinyDet, out: str, size: tuple[int, int], description: str) -> None:
    model.eval()
    model.export_decode = True
    h, w = size
    x = torch.zeros(1, 3, h, w)
    torch.onnx.export(
        model,
        (x,),
        out,
        input_names=["images"],
        output_names=["output0"],
        opset_version=OPSET,
        dynamo=False,
        do_constant_folding=True,
    )
    m = onnx.load(out)
    names = "{" + ", ".join(f"{i}: '{n}'" for i, n in enumerate(CLASS_NAMES)) + "}"
    meta = {
        "names": names,
        "imgsz": f"[{h}, {w}]",
        "stride": "32",
        "task": "detect",
        "author": "mgmot train/",
        "description": description,
    }
    del m.metadata_props[:]
    for k, v in meta.items():
        p = m.metadata_props.add()
        p.key, p.value = k, v
    m.producer_name = "mgmot-train"
    onnx.checker.check_model(m)
    onnx.save(m, out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ckpt")
    ap.add_argument("--untrained", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--size", default="448,800", help="input H,W (multiples of 32) or S for S x S")
    ap.add_argument("--widths", default="16,32,48,64,96")
    ap.add_argument("--out", required=True)
    ap.add_argument("--description", default="mgmot TinyDet swimmer/boat detector")
    args = ap.parse_args()
    torch.manual_seed(args.seed)
    model = TinyDet(widths=tuple(int(w) for w in args.widths.split(",")))
    if args.ckpt:
        state = torch.load(args.ckpt, map_location="cpu")
        model.load_state_dict(state["model"])
    elif not args.untrained:
        raise SystemExit("give --ckpt or --untrained")
    try:
        dims = [int(v) for v in args.size.split(",")]
    except ValueError:
        dims = []
    if len(dims) not in (1, 2) or any(d <= 0 or d % 32 for d in dims):
        raise SystemExit(f"--size {args.size}: expected H,W or S, each a positive multiple of 32")
    size = (dims[0], dims[-1])
    export(model, args.out, size, args.description)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
