#!/usr/bin/env python3
"""tract vs ONNX Runtime on one model over a folder of frames, through `mgmot detect --json`.

Matches every detection of one backend scoring at least --min-score to the
other backend's detection of the same image and class with the highest IoU,
and prints the largest box-coordinate and score differences (and any
detection without a partner at IoU >= 0.5). Each backend runs in its own
process, as the test does (tests/detect_cli.rs).

Usage: ORT_DYLIB_PATH=... python3 scripts/detect_parity.py --model models/mgmot-det-int8.onnx DIR [--tile]
"""

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run(binary, model, frames, backend, extra):
    cmd = [binary, "detect", "--json", "--model", model, frames, "--backend", backend, "--score", "0.2", *extra]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def iou(a, b):
    ax2, ay2, bx2, by2 = a[0] + a[2], a[1] + a[3], b[0] + b[2], b[1] + b[3]
    iw = max(0.0, min(ax2, bx2) - max(a[0], b[0]))
    ih = max(0.0, min(ay2, by2) - max(a[1], b[1]))
    inter = iw * ih
    return inter / max(1e-9, a[2] * a[3] + b[2] * b[3] - inter)


def compare(a, b, min_score):
    box_diff, score_diff, unmatched, n = 0.0, 0.0, [], 0
    for x in a:
        if x["score"] < min_score:
            continue
        n += 1
        cands = [y for y in b if y["image_id"] == x["image_id"] and y["category_id"] == x["category_id"]]
        best = max(cands, key=lambda y: iou(x["bbox"], y["bbox"]), default=None)
        if best is None or iou(x["bbox"], best["bbox"]) < 0.5:
            unmatched.append(x)
            continue
        box_diff = max(box_diff, max(abs(p - q) for p, q in zip(x["bbox"], best["bbox"])))
        score_diff = max(score_diff, abs(x["score"] - best["score"]))
    return n, box_diff, score_diff, unmatched


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", required=True)
    ap.add_argument("frames", help="an image or a folder of images")
    ap.add_argument("--bin", default=str(ROOT / "target" / "debug" / "mgmot"))
    ap.add_argument("--min-score", type=float, default=0.25)
    ap.add_argument("--tile", action="store_true")
    args = ap.parse_args()
    extra = ["--tile"] if args.tile else []
    tract = run(args.bin, args.model, args.frames, "tract", extra)
    ort = run(args.bin, args.model, args.frames, "onnxruntime", extra)
    worst = {"box_px": 0.0, "score": 0.0, "unmatched": 0, "compared": 0}
    for name, a, b in (("tract->onnxruntime", tract, ort), ("onnxruntime->tract", ort, tract)):
        n, box, score, unmatched = compare(a, b, args.min_score)
        print(f"{name}: {n} detections >= {args.min_score}, max |box| {box:.4f} px, max |score| {score:.6f}, "
              f"{len(unmatched)} without a partner")
        for x in unmatched:
            print(f"  unmatched: {x}")
        worst = {
            "box_px": max(worst["box_px"], box),
            "score": max(worst["score"], score),
            "unmatched": worst["unmatched"] + len(unmatched),
            "compared": worst["compared"] + n,
        }
    print(json.dumps(worst))
    sys.exit(0)


if __name__ == "__main__":
    main()
