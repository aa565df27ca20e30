#!/usr/bin/env python3
"""Cross-check `mgmot eval` MOTA and IDF1 against py-motmetrics (PyPI `motmetrics`).

Generates random cases (the generator of eval_trackeval_harness.py), evaluates
them with `mgmot eval --json` and with motmetrics (IoU distance, threshold 0.5,
ground-truth rows with conf 0 dropped, as in mgmot's class-agnostic default),
and compares MOTA and IDF1 per sequence and over all sequences.

    python3 scripts/crosscheck_motmetrics.py --mgmot target/debug/mgmot --cases 50

Exit status: 0 all agree within 1e-4, 1 some differ, 3 python packages missing
(the reason is printed; `tests/eval_motmetrics.rs` then skips).
"""
import argparse
import json
import os
import random
import subprocess
import sys
import tempfile

TOLERANCE = 1e-4

try:
    import numpy as np
    # motmetrics 1.4 still calls np.asfarray, which numpy 2 removed.
    if not hasattr(np, "asfarray"):
        np.asfarray = lambda a, dtype=float: np.asarray(a, dtype=dtype)
    import motmetrics as mm
except ImportError as e:  # pragma: no cover - depends on the machine
    print("SKIP: py-motmetrics cross-check needs numpy and motmetrics (pip install motmetrics): %s" % e)
    sys.exit(3)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from eval_trackeval_harness import random_sequence, write_rows  # noqa: E402


def accumulate(gt_rows, pred_rows):
    acc = mm.MOTAccumulator(auto_id=True)
    gt_rows = [r for r in gt_rows if r[6] != 0]
    frames = sorted({r[0] for r in gt_rows} | {r[0] for r in pred_rows})
    for f in frames:
        g = [r for r in gt_rows if r[0] == f]
        p = [r for r in pred_rows if r[0] == f]
        dist = mm.distances.iou_matrix([r[2:6] for r in g], [r[2:6] for r in p], max_iou=0.5)
        acc.update([r[1] for r in g], [r[1] for r in p], np.asarray(dist).reshape(len(g), len(p)))
    return acc


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mgmot", required=True, help="path of the mgmot binary")
    ap.add_argument("--cases", type=int, default=30)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    rng = random.Random(args.seed)
    mh = mm.metrics.create()
    compared, problems, worst = 0, [], 0.0
    for case in range(args.cases):
        # No twin objects: where several assignments are optimal, motmetrics and
        # TrackEval break ties differently (different IDSW), and mgmot follows
        # TrackEval (checked by eval_trackeval_harness.py).
        sequences = {"seq%02d" % i: random_sequence(rng, twins=False) for i in range(rng.randint(1, 4))}
        with tempfile.TemporaryDirectory() as work:
            for name, (_, gt, pred) in sequences.items():
                write_rows(os.path.join(work, "gt", name + ".txt"), gt, None)
                write_rows(os.path.join(work, "pred", name + ".txt"), pred, "class")
            out = subprocess.run([args.mgmot, "eval", "--gt", os.path.join(work, "gt"), "--pred",
                                  os.path.join(work, "pred"), "--json"], check=True, capture_output=True, text=True)
            ours = json.loads(out.stdout)
        names = sorted(sequences)
        accs = [accumulate(sequences[n][1], sequences[n][2]) for n in names]
        summary = mh.compute_many(accs, metrics=["mota", "idf1", "num_objects"], names=names,
                                  generate_overall=True)
        for name in names + ["OVERALL"]:
            row = summary.loc[name]
            if row["num_objects"] == 0:
                continue  # MOTA has no denominator; TrackEval and motmetrics define it differently
            mine = ours["combined"] if name == "OVERALL" else ours["sequences"][name]
            for ours_key, theirs_key in (("MOTA", "mota"), ("IDF1", "idf1")):
                d = abs(mine[ours_key] - float(row[theirs_key]))
                worst = max(worst, d)
                compared += 1
                if d > TOLERANCE:
                    problems.append("case %d %s %s: mgmot %r, motmetrics %r"
                                    % (case, name, ours_key, mine[ours_key], float(row[theirs_key])))
    print("\n".join(problems))
    print("%d MOTA/IDF1 values compared, %d differ by more than %g, max abs difference %.3g"
          % (compared, len(problems), TOLERANCE, worst))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
