#!/usr/bin/env python3
"""Compare `mgmot eval` with real TrackEval on random MOTChallenge cases.

TrackEval is not part of this repository: pass the path of a TrackEval checkout
(https://github.com/JonathonLuiten/TrackEval) with --trackeval; it needs numpy
and scipy. The TrackEval configuration that `mgmot eval` reproduces is the
MotChallenge2DBox dataset with BENCHMARK='MOT15' / DO_PREPROC=False (gt rows
with conf 0 dropped, every tracker row kept, no distractor removal); per class
evaluation is TrackEval run on each class's rows separately, then
combine_classes_class_averaged / combine_classes_det_averaged.

    python3 scripts/eval_trackeval_harness.py --trackeval /work/trackeval \
        --mgmot target/release/mgmot --cases 200 [--fixtures tests/fixtures/eval --keep-fixtures 8]

Exit status 1 when any key differs by more than 1e-4 (counts must be equal).
"""
import argparse
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile

RATIO_KEYS = ["HOTA", "DetA", "AssA", "DetRe", "DetPr", "AssRe", "AssPr", "LocA",
              "MOTA", "MOTP", "IDF1", "IDR", "IDP", "Recall", "Precision"]
COUNT_KEYS = ["IDSW", "Frag", "MT", "PT", "ML", "FP", "FN"]
TOLERANCE = 1e-4


# ----------------------------------------------------------------------------
# Random cases
# ----------------------------------------------------------------------------

def fmt(v):
    return repr(float(v)) if not float(v).is_integer() else str(int(v))


def random_sequence(rng, twins=True, max_frames=40, max_objects=8):
    """Returns (n_frames, gt_rows, pred_rows); rows are [frame, id, x, y, w, h, conf, class].

    With `twins`, some cases get two objects moving exactly alike, so that the
    assignment has several optima and TrackEval's tie-breaking decides."""
    kind = rng.choices(["normal", "gt_empty", "pred_empty", "both_empty"], [16, 2, 2, 1])[0]
    n_frames = rng.randint(1, max_frames)
    integer_boxes = rng.random() < 0.5
    noise = rng.choice([0.0, 0.02, 0.1, 0.25])
    p_detect = rng.uniform(0.5, 1.0)
    gt, pred = [], []
    next_pred_id = 1
    fp_id = 5000
    empty_frames = {f for f in range(1, n_frames + 1) if rng.random() < 0.1}
    objects = []
    for obj in range(rng.randint(0, max_objects)):
        start = rng.randint(1, n_frames)
        end = rng.randint(start, n_frames)
        objects.append({
            "gt_id": obj + 1 + rng.choice([0, 0, 10, 100]),
            "start": start, "end": end,
            "x": rng.uniform(0, 200), "y": rng.uniform(0, 200),
            "w": rng.uniform(5, 60), "h": rng.uniform(5, 60),
            "vx": rng.uniform(-5, 5), "vy": rng.uniform(-5, 5),
            "cls": rng.choice([1, 1, 2, 3]),
            "ignored": rng.random() < 0.1,
            "pred_id": None,
        })
    # Twins: an object that moves exactly like another one, so that IoUs and
    # assignment scores tie and the solver's tie-breaking is exercised.
    if twins and len(objects) >= 2 and rng.random() < 0.3:
        a, b = rng.sample(objects, 2)
        for k in ("start", "end", "x", "y", "w", "h", "vx", "vy"):
            b[k] = a[k]
    # Ensure gt ids are unique.
    seen = set()
    for o in objects:
        while o["gt_id"] in seen:
            o["gt_id"] += 1
        seen.add(o["gt_id"])
    for o in objects:
        o["pred_id"] = next_pred_id
        next_pred_id += 1

    for f in range(1, n_frames + 1):
        # Identity switches: fresh ids or swaps between two objects.
        if objects and rng.random() < 0.08:
            o = rng.choice(objects)
            o["pred_id"] = next_pred_id
            next_pred_id += 1
        if len(objects) >= 2 and rng.random() < 0.05:
            a, b = rng.sample(objects, 2)
            a["pred_id"], b["pred_id"] = b["pred_id"], a["pred_id"]
        for o in objects:
            if not (o["start"] <= f <= o["end"]):
                continue
            t = f - o["start"]
            x, y, w, h = o["x"] + o["vx"] * t, o["y"] + o["vy"] * t, o["w"], o["h"]
            if integer_boxes:
                x, y, w, h = round(x), round(y), max(1, round(w)), max(1, round(h))
            if f not in empty_frames and rng.random() > 0.05:
                conf = 0 if (o["ignored"] or rng.random() < 0.03) else 1
                gt.append([f, o["gt_id"], x, y, w, h, conf, o["cls"]])
            if rng.random() < p_detect:
                px = x + rng.gauss(0, noise * w)
                py = y + rng.gauss(0, noise * h)
                pw = max(0.5, w * (1 + rng.gauss(0, noise)))
                ph = max(0.5, h * (1 + rng.gauss(0, noise)))
                if integer_boxes:
                    px, py, pw, ph = round(px), round(py), max(1, round(pw)), max(1, round(ph))
                cls = o["cls"] if rng.random() > 0.1 else rng.choice([1, 2, 3])
                pred.append([f, o["pred_id"], px, py, pw, ph, round(rng.random(), 3), cls])
        # False positives, sometimes as short tracks.
        for _ in range(rng.choice([0, 0, 0, 1, 2])):
            fp_id += 1
            x, y = rng.uniform(0, 250), rng.uniform(0, 250)
            w, h = rng.uniform(5, 60), rng.uniform(5, 60)
            if integer_boxes:
                x, y, w, h = round(x), round(y), round(w), round(h)
            pred.append([f, fp_id, x, y, w, h, 0.5, rng.choice([1, 2, 3])])
    if kind in ("gt_empty", "both_empty"):
        gt = []
    if kind in ("pred_empty", "both_empty"):
        pred = []
    return n_frames, gt, pred


def write_rows(path, rows, pred_class_column):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as fp:
        for r in rows:
            f, i, x, y, w, h, conf, cls = r
            if pred_class_column is None:
                fp.write("%d,%d,%s,%s,%s,%s,%s,%d,1\n" % (f, i, fmt(x), fmt(y), fmt(w), fmt(h), fmt(conf), cls))
            else:
                c = cls if pred_class_column == "class" else -1
                fp.write("%d,%d,%s,%s,%s,%s,%s,%d,-1,-1\n" % (f, i, fmt(x), fmt(y), fmt(w), fmt(h), fmt(conf), c))


def write_case(root, sequences, class_filter=None, pred_class_column="class"):
    """Writes gt/<seq>/gt/gt.txt (+ seqinfo.ini) and pred/<seq>.txt under root."""
    for name, (n_frames, gt, pred) in sequences.items():
        if class_filter is not None:
            gt = [r for r in gt if r[7] == class_filter]
            pred = [r for r in pred if r[7] == class_filter]
        write_rows(os.path.join(root, "gt", name, "gt", "gt.txt"), gt, None)
        with open(os.path.join(root, "gt", name, "seqinfo.ini"), "w") as fp:
            fp.write("[Sequence]\nname=%s\nseqLength=%d\n" % (name, n_frames))
        write_rows(os.path.join(root, "pred", name + ".txt"), pred, pred_class_column)


# ----------------------------------------------------------------------------
# TrackEval
# ----------------------------------------------------------------------------

def import_trackeval(path):
    import numpy as np
    # TrackEval still uses the aliases numpy removed in 1.24.
    for alias, value in (("float", float), ("int", int)):
        if alias not in np.__dict__:
            setattr(np, alias, value)
    sys.path.insert(0, path)
    import trackeval  # noqa: E402
    return trackeval


def summarise(metrics):
    import numpy as np
    h, c, i = metrics["HOTA"], metrics["CLEAR"], metrics["Identity"]
    out = {k: float(np.mean(h[k])) for k in ["HOTA", "DetA", "AssA", "DetRe", "DetPr", "AssRe", "AssPr", "LocA"]}
    out.update({"MOTA": float(c["MOTA"]), "MOTP": float(c["MOTP"]), "IDF1": float(i["IDF1"]),
                "IDR": float(i["IDR"]), "IDP": float(i["IDP"]), "IDSW": int(c["IDSW"]), "Frag": int(c["Frag"]),
                "MT": int(c["MT"]), "PT": int(c["PT"]), "ML": int(c["ML"]), "FP": int(c["CLR_FP"]),
                "FN": int(c["CLR_FN"]), "Recall": float(c["CLR_Re"]), "Precision": float(c["CLR_Pr"])})
    return out


def run_trackeval(te, root, seq_lengths):
    """Runs TrackEval on root/gt + root/pred; returns (per-seq raw, combined raw) metric dicts."""
    tracker_root = os.path.join(root, "trackers")
    os.makedirs(os.path.join(tracker_root, "t", "data"), exist_ok=True)
    for name in seq_lengths:
        shutil.copy(os.path.join(root, "pred", name + ".txt"), os.path.join(tracker_root, "t", "data", name + ".txt"))
    eval_config = te.Evaluator.get_default_eval_config()
    eval_config.update({"USE_PARALLEL": False, "PRINT_RESULTS": False, "PRINT_CONFIG": False,
                        "TIME_PROGRESS": False, "OUTPUT_SUMMARY": False, "OUTPUT_DETAILED": False,
                        "PLOT_CURVES": False, "BREAK_ON_ERROR": True, "RETURN_ON_ERROR": False,
                        "DISPLAY_LESS_PROGRESS": True, "OUTPUT_EMPTY_CLASSES": True})
    dataset_config = te.datasets.MotChallenge2DBox.get_default_dataset_config()
    dataset_config.update({"GT_FOLDER": os.path.join(root, "gt"), "TRACKERS_FOLDER": tracker_root,
                           "TRACKERS_TO_EVAL": ["t"], "BENCHMARK": "MOT15", "DO_PREPROC": False,
                           "SKIP_SPLIT_FOL": True, "SEQ_INFO": dict(seq_lengths), "PRINT_CONFIG": False,
                           "OUTPUT_FOLDER": os.path.join(root, "te_out")})
    evaluator = te.Evaluator(eval_config)
    metrics = [te.metrics.HOTA(), te.metrics.CLEAR({"PRINT_CONFIG": False}),
               te.metrics.Identity({"PRINT_CONFIG": False})]
    import contextlib
    import io
    with contextlib.redirect_stdout(io.StringIO()):
        res, msg = evaluator.evaluate([te.datasets.MotChallenge2DBox(dataset_config)], metrics)
    if msg["MotChallenge2DBox"]["t"] != "Success":
        raise RuntimeError("TrackEval failed: %s" % msg["MotChallenge2DBox"]["t"])
    out = res["MotChallenge2DBox"]["t"]
    per_seq = {s: out[s]["pedestrian"] for s in seq_lengths}
    return per_seq, out["COMBINED_SEQ"]["pedestrian"], metrics


def trackeval_expected(te, work, sequences, per_class):
    lengths = {name: n for name, (n, _, _) in sequences.items()}
    te_root = os.path.join(work, "te_all")
    write_case(te_root, sequences, pred_class_column="minus_one")
    per_seq, combined, _ = run_trackeval(te, te_root, lengths)
    agnostic = {"sequences": {s: summarise(per_seq[s]) for s in sorted(per_seq)}, "combined": summarise(combined)}
    if not per_class:
        return agnostic, None
    classes = sorted({r[7] for _, gt, _ in sequences.values() for r in gt if r[6] != 0}
                     | {r[7] for _, _, pred in sequences.values() for r in pred})
    by_class, combined_by_class, metrics = {}, {}, None
    for c in classes:
        root = os.path.join(work, "te_class_%d" % c)
        write_case(root, sequences, class_filter=c, pred_class_column="minus_one")
        per_seq, combined, metrics = run_trackeval(te, root, lengths)
        by_class[str(c)] = {"sequences": {s: summarise(per_seq[s]) for s in sorted(per_seq)},
                            "combined": summarise(combined)}
        combined_by_class[c] = combined
    result = {"classes": by_class, "class_averaged": None, "detection_averaged": None}
    if classes:
        cls_av, det_av = {}, {}
        for m in metrics:
            name = m.get_name()
            parts = {c: combined_by_class[c][name] for c in classes}
            cls_av[name] = m.combine_classes_class_averaged(parts)
            det_av[name] = m.combine_classes_det_averaged(parts)
        result["class_averaged"] = summarise(cls_av)
        result["detection_averaged"] = summarise(det_av)
    return agnostic, result


# ----------------------------------------------------------------------------
# Comparison
# ----------------------------------------------------------------------------

def compare(expected, actual, where, worst):
    """Returns a list of mismatch messages; updates worst[0] with the max abs diff."""
    problems = []
    if isinstance(expected, dict) and set(expected) & set(RATIO_KEYS):
        for k in RATIO_KEYS:
            d = abs(expected[k] - actual[k])
            worst[0] = max(worst[0], d)
            if d > TOLERANCE:
                problems.append("%s.%s: TrackEval %r, mgmot %r" % (where, k, expected[k], actual[k]))
        for k in COUNT_KEYS:
            if expected[k] != actual[k]:
                problems.append("%s.%s: TrackEval %r, mgmot %r" % (where, k, expected[k], actual[k]))
        return problems
    if isinstance(expected, dict):
        if set(expected) != set(actual or {}):
            return ["%s: keys differ: %s vs %s" % (where, sorted(expected), sorted(actual or {}))]
        for k in expected:
            problems += compare(expected[k], actual[k], where + "." + k, worst)
        return problems
    if expected != actual:
        problems.append("%s: TrackEval %r, mgmot %r" % (where, expected, actual))
    return problems


def run_mgmot(binary, root, per_class):
    cmd = [binary, "eval", "--gt", os.path.join(root, "gt"), "--pred", os.path.join(root, "pred"), "--json"]
    if per_class:
        cmd.append("--per-class")
    out = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trackeval", required=True, help="path of a TrackEval checkout")
    ap.add_argument("--mgmot", required=True, help="path of the mgmot binary")
    ap.add_argument("--cases", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--max-frames", type=int, default=40, help="frames per sequence at most")
    ap.add_argument("--max-objects", type=int, default=8, help="ground-truth objects per sequence at most")
    ap.add_argument("--fixtures", help="write the first --keep-fixtures cases here, with TrackEval's results")
    ap.add_argument("--keep-fixtures", type=int, default=0)
    args = ap.parse_args()

    te = import_trackeval(args.trackeval)
    rng = random.Random(args.seed)
    worst = [0.0]
    failures = 0
    for case in range(args.cases):
        sequences = {"seq%02d" % i: random_sequence(rng, True, args.max_frames, args.max_objects)
                     for i in range(rng.randint(1, 4))}
        per_class = case % 2 == 0
        with tempfile.TemporaryDirectory() as work:
            expected, expected_pc = trackeval_expected(te, work, sequences, per_class)
            ours_root = os.path.join(work, "ours")
            write_case(ours_root, sequences)
            actual = run_mgmot(args.mgmot, ours_root, False)
            problems = compare(expected, actual, "case%03d" % case, worst)
            if per_class:
                actual_pc = run_mgmot(args.mgmot, ours_root, True)
                problems += compare(expected_pc, actual_pc, "case%03d.per_class" % case, worst)
            if problems:
                failures += 1
                print("\n".join(problems[:10]))
                keep = os.path.join(tempfile.gettempdir(), "mgmot_failed_case%03d" % case)
                shutil.rmtree(keep, ignore_errors=True)
                shutil.copytree(ours_root, keep)
                print("case kept in", keep)
            if args.fixtures and case < args.keep_fixtures:
                dest = os.path.join(args.fixtures, "case%03d" % case)
                shutil.rmtree(dest, ignore_errors=True)
                shutil.copytree(ours_root, dest)
                with open(os.path.join(dest, "expected.json"), "w") as fp:
                    json.dump(expected, fp, indent=1, sort_keys=True)
                if per_class:
                    with open(os.path.join(dest, "expected_per_class.json"), "w") as fp:
                        json.dump(expected_pc, fp, indent=1, sort_keys=True)
    print("%d cases, %d matched TrackEval within %g, max abs difference %.3g"
          % (args.cases, args.cases - failures, TOLERANCE, worst[0]))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
