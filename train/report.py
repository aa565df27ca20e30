"""The model card's tables from ``metrics.json`` (what ``run.sh`` writes), as Markdown.

Usage: python report.py runs/sim/metrics.json   (or models/metrics.json)
"""

from __future__ import annotations

import json
import sys

SPLITS = {"tuning": "tuning seeds", "tuning-lossless": "tuning seeds, lossless PNG", "heldout": "held-out seeds", "conditions": "held-out conditions",
          "heldout-lossless": "held-out seeds, lossless PNG", "val": "val split"}
SHORT = {"life_saving_appliances": "lifesaving"}


def splits(doc: dict):
    """(split, report) pairs: the main models' splits, then the tile model's (``tile_model``)."""
    for split, report in doc.items():
        if split == "tile_model":
            yield from report.items()
        else:
            yield split, report


def per_class_table(doc: dict) -> list[str]:
    names = None
    rows = []
    for split, report in splits(doc):
        for model, modes in report["models"].items():
            for mode, m in modes.items():
                ap = m["ap50_per_class"]
                names = names or list(report["ground_truth_boxes"].keys())
                small = m.get("recall_small", {})
                rec = small.get("recall")
                rows.append(
                    f"| {SPLITS.get(split, split)} | {model.replace('mgmot-det-', '').replace('.onnx', '')} | {mode} | {m['frames']} | "
                    + " | ".join("-" if n not in ap else f"{ap[n]:.3f}" for n in names)
                    + f" | **{m['map50']:.3f}** | {'-' if rec is None else f'{rec:.3f}'} ({small.get('objects', 0)}) |"
                )
    head = (
        "| split | model | frames | n | "
        + " | ".join(SHORT.get(n, n) for n in names)
        + " | mAP50 | recall < 12 px (objects) |"
    ).replace("| frames | n |", "| mode | frames |")
    return [head, "|" + " --- |" * (head.count("|") - 1), *rows]


def confusion_tables(doc: dict, model_suffix: str = "fp32") -> list[str]:
    out = []
    for split, report in splits(doc):
        for model, modes in report["models"].items():
            if model_suffix not in model:
                continue
            for mode, m in modes.items():
                c = m["confusion"]
                cols = [SHORT.get(n, n) for n in c["cols_detected"]]
                out.append(f"\n{SPLITS.get(split, split)}, {model}, {mode} ({m['frames']} frames, score >= {c['score_threshold']}):\n")
                out.append("| true \\ detected | " + " | ".join(cols) + " |")
                out.append("|" + " --- |" * (len(cols) + 1))
                for label, row in zip(c["rows_true"], c["counts"]):
                    out.append(f"| {SHORT.get(label, label)} | " + " | ".join(str(v) for v in row) + " |")
    return out


def main():
    doc = json.load(open(sys.argv[1]))
    print("\n".join(per_class_table(doc)))
    print("\n".join(confusion_tables(doc)))


if __name__ == "__main__":
    main()
