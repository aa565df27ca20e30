#!/usr/bin/env python3
"""Diagnostics for long-gap re-identification on simulated sequences.

Two measurements behind the docs/benchmark.md "Decide with measurements" items (issue 14):

``size GT_DIR DET``
    Could physical size break ties between swimmers? For every true swimmer (``world.csv``,
    visibility >= 0.9) and every frame, the size index ``sqrt(box area) * slant range``
    (proportional to the physical size perpendicular to the line of sight; the focal length
    is the same for every frame) from the true box and from the detection that matches it
    (IoU >= 0.5, ``DET`` in MOTChallenge layout). A track segment (frames at most 1 s apart,
    at least 10 observations) gives the log of its mean. The intraclass correlation
    ``1 - within-object variance / total variance`` over the segments says how much of the
    spread is the object rather than the view: near 1 separates objects, near 0 does not.

``perfect-reid GT_DIR OUT_DIR RELABELLED``
    How much of the online loss is the ReID decisions? ``OUT_DIR`` is what
    ``mgmot track --mode online --json --out OUT_DIR`` wrote (``summary.json`` with the merges and
    the results file it names). Each raw track segment (an id's rows between the
    merges that re-label it) takes the true id that most of its rows match (IoU >= 0.5, one
    optimal assignment per frame), as if every ReID decision were right and nothing else
    changed; rows matching nothing keep a fresh id. Writes RELABELLED (MOTChallenge); score
    it with ``mgmot eval --gt GT_DIR/gt/gt.txt --pred RELABELLED``.

``decisions GT_DIR OUT_DIR [--results FILE]``
    Which online ReID decisions went wrong, and after how long a gap? Each merge in
    ``OUT_DIR/summary.json`` links a new track to an ended one: it is right when the old id's
    rows just before the new track appeared (the last run of rows, frames at most 3 apart,
    before it) and its rows after the merge take the same true id (majority, IoU >= 0.5, one
    optimal assignment per frame). An id never merged into and never merged is a "new
    object" decision: right when its true id had no earlier rows under another id, otherwise
    a missed link. Prints the counts and, for the wrong and missed ones, the frame, ids and gap
    in seconds. ``--results`` names the results file when it was moved from ``OUT_DIR``.

Usage (the folder is what ``mgmot-sim detections ... --gt-dir`` writes):

    mgmot-sim detections -s sector_search --out /tmp/x/det.txt --gt-dir /tmp/x/gt
    python3 scripts/reid_diagnostics.py size /tmp/x/gt /tmp/x/det.txt
    mgmot track --annotations /tmp/x/gt/annotations.json --detections /tmp/x/det.txt \\
        --mode online --json --out /tmp/x/online
    python3 scripts/reid_diagnostics.py perfect-reid /tmp/x/gt /tmp/x/online /tmp/x/perfect.txt
    mgmot eval --gt /tmp/x/gt/gt/gt.txt --pred /tmp/x/perfect.txt
    python3 scripts/reid_diagnostics.py decisions /tmp/x/gt /tmp/x/online

Needs numpy and scipy (``scripts/test.sh`` installs them into ``.venv``).
"""

from __future__ import annotations

import argparse
import collections
import csv
import datetime
import json
import math
import os
import sys

import numpy as np
from scipy.optimize import linear_sum_assignment


def read_mot(path: str) -> dict[int, list[tuple[int, float, float, float, float]]]:
    """MOTChallenge rows by frame: (id, x, y, w, h)."""
    rows: dict[int, list] = collections.defaultdict(list)
    with open(path, encoding="utf-8") as f:
        for line in f:
            p = line.strip().split(",")
            if len(p) < 6:
                continue
            rows[int(float(p[0]))].append((int(float(p[1])), *map(float, p[2:6])))
    return rows


def iou(a, b) -> float:
    """IoU of two (x, y, w, h) boxes."""
    iw = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    ih = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = iw * ih
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def segments(frames: list[int], max_gap: int) -> list[list[int]]:
    """Splits sorted frame numbers where consecutive ones are more than max_gap apart."""
    out: list[list[int]] = []
    for f in frames:
        if out and f - out[-1][-1] <= max_gap:
            out[-1].append(f)
        else:
            out.append([f])
    return out


def icc(values_by_object: dict[int, list[float]]) -> tuple[float, float, float, int]:
    """(total sd, within-object sd, intraclass correlation, segments)."""
    all_v = np.array([v for vs in values_by_object.values() for v in vs])
    within = [np.var(vs) for vs in values_by_object.values() if len(vs) > 1]
    if len(all_v) < 2 or not within or all_v.var() == 0:
        raise SystemExit("not enough repeated segments to compare")
    w = float(np.mean(within))
    return float(all_v.std()), math.sqrt(w), 1.0 - w / float(all_v.var()), len(all_v)


def cmd_size(args: argparse.Namespace) -> None:
    with open(os.path.join(args.gt_dir, "seqinfo.ini"), encoding="utf-8") as f:
        fps = next(float(l.split("=")[1]) for l in f if l.startswith("frameRate"))
    cam = {}
    with open(os.path.join(args.gt_dir, "camera.csv"), encoding="utf-8") as f:
        for r in csv.DictReader(f):
            cam[int(r["frame"])] = np.array(
                [float(r["north_m"]), float(r["east_m"]), float(r["down_m"])]
            )
    dets = read_mot(args.det)
    obs: dict[int, list] = collections.defaultdict(list)
    with open(os.path.join(args.gt_dir, "world.csv"), encoding="utf-8") as f:
        for r in csv.DictReader(f):
            if r["class"] != args.object_class or float(r["visibility"]) < 0.9:
                continue
            fr = int(r["frame"])
            if fr not in cam:
                continue
            rng = float(np.linalg.norm(
                np.array([float(r["north_m"]), float(r["east_m"]), 0.0]) - cam[fr]))
            tb = [float(r[k]) for k in ("box_x", "box_y", "box_w", "box_h")]
            best = max(dets.get(fr, []), key=lambda d: iou(d[1:], tb), default=None)
            det = best[1:] if best is not None and iou(best[1:], tb) >= 0.5 else None
            obs[int(r["id"])].append((
                fr,
                math.sqrt(tb[2] * tb[3]) * rng,
                math.sqrt(det[2] * det[3]) * rng if det is not None else None,
            ))
    if not obs:
        raise SystemExit(f"no visible objects of class {args.object_class!r}")
    for key, name in ((1, "true boxes"), (2, "detections")):
        by_obj: dict[int, list[float]] = collections.defaultdict(list)
        for oid, xs in obs.items():
            at = {x[0]: x for x in xs}
            for seg in segments(sorted(at), max_gap=int(fps)):
                vals = [at[f][key] for f in seg if at[f][key] is not None]
                if len(vals) >= 10:
                    by_obj[oid].append(math.log(float(np.mean(vals))))
        total, within, c, n = icc(by_obj)
        print(f"{name}: {n} segments of {len(by_obj)} objects; log size index sd {total:.3f}, "
              f"within one object {within:.3f}; intraclass correlation {c:.2f}")


def true_ids_by_frame(gt, pred) -> dict[tuple[int, int], int]:
    """(frame, predicted id) -> the true id its box matches (IoU >= 0.5, optimal per frame)."""
    out: dict[tuple[int, int], int] = {}
    for fr, ps in pred.items():
        gs = gt.get(fr, [])
        if not gs:
            continue
        cost = np.array([[iou(g[1:], p[1:]) for p in ps] for g in gs])
        for a, b in zip(*linear_sum_assignment(-cost)):
            if cost[a, b] >= 0.5:
                out[(fr, ps[b][0])] = gs[a][0]
    return out


def cmd_perfect_reid(args: argparse.Namespace) -> None:
    with open(os.path.join(args.out_dir, "summary.json"), encoding="utf-8") as f:
        videos = json.load(f)["videos"]
    if len(videos) != 1:
        raise SystemExit("expected one video in summary.json")
    # The results file sits beside summary.json, named after the video.
    results = [os.path.join(args.out_dir, os.path.basename(videos[0]["mot_results"]))]
    gt = read_mot(os.path.join(args.gt_dir, "gt", "gt.txt"))
    pred = read_mot(results[0])
    # A merge at frame F re-labels the new track's rows from F on with the old id, so the
    # old id's rows split there.
    splits: dict[int, list[int]] = collections.defaultdict(list)
    for m in videos[0]["merges"]:
        splits[m["merged_into_id"]].append(m["frame_index"] + 1)

    def segment(pid: int, fr: int) -> tuple[int, int]:
        return pid, sum(1 for s in splits[pid] if fr >= s)

    votes: dict[tuple[int, int], collections.Counter] = collections.defaultdict(
        collections.Counter)
    for (fr, pid), true_id in true_ids_by_frame(gt, pred).items():
        votes[segment(pid, fr)][true_id] += 1
    fresh = max((i for ps in gt.values() for i, *_ in ps), default=0) + 1_000_000
    new_id: dict[tuple[int, int], int] = {}
    used: set[tuple[int, int]] = set()
    dup: dict[tuple[int, int], int] = {}
    n_rows = 0
    with open(results[0], encoding="utf-8") as src, open(args.relabelled, "w",
                                                           encoding="utf-8") as dst:
        for line in src:
            p = line.strip().split(",")
            if len(p) < 6:
                continue
            fr, pid = int(float(p[0])), int(float(p[1]))
            seg = segment(pid, fr)
            if seg not in new_id:
                if votes[seg]:
                    new_id[seg] = votes[seg].most_common(1)[0][0]
                else:
                    new_id[seg] = fresh
                    fresh += 1
            i = new_id[seg]
            if (fr, i) in used:
                # Two segments on one object at once (a duplicate track): the second keeps
                # an id of its own.
                if seg not in dup:
                    dup[seg] = fresh
                    fresh += 1
                i = dup[seg]
            used.add((fr, i))
            p[1] = str(i)
            dst.write(",".join(p) + "\n")
            n_rows += 1
    print(f"{n_rows} rows, {len(new_id)} raw segments -> {args.relabelled}")


def cmd_decisions(args: argparse.Namespace) -> None:
    with open(os.path.join(args.out_dir, "summary.json"), encoding="utf-8") as f:
        videos = json.load(f)["videos"]
    if len(videos) != 1:
        raise SystemExit("expected one video in summary.json")
    results = args.results or os.path.join(
        args.out_dir, os.path.basename(videos[0]["mot_results"]))
    gt = read_mot(os.path.join(args.gt_dir, "gt", "gt.txt"))
    pred = read_mot(results)
    fps = 30.0
    ann = os.path.join(args.gt_dir, "annotations.json")
    if os.path.exists(ann):
        with open(ann, encoding="utf-8") as f:
            images = json.load(f).get("images", [])
        stamps = sorted(datetime.datetime.fromisoformat(i["date_time"]).timestamp()
                        for i in images if "date_time" in i)
        if len(stamps) > 1 and stamps[-1] > stamps[0]:
            fps = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    truth = true_ids_by_frame(gt, pred)
    rows_of: dict[int, list[int]] = collections.defaultdict(list)
    for fr, ps in pred.items():
        for p in ps:
            rows_of[p[0]].append(fr)
    for frames in rows_of.values():
        frames.sort()

    def majority(pid: int, frames) -> int | None:
        c = collections.Counter(truth[(fr, pid)] for fr in frames if (fr, pid) in truth)
        return c.most_common(1)[0][0] if c else None

    merges = sorted(videos[0]["merges"], key=lambda m: m["frame_index"])
    splits: dict[int, list[int]] = collections.defaultdict(list)
    for m in merges:
        # frame_index counts from 0, the results' frames from 1.
        splits[m["merged_into_id"]].append(m["frame_index"] + 1)
    wrong, right = [], 0
    for m in merges:
        pid, at = m["merged_into_id"], m["frame_index"] + 1
        later = [s for s in splits[pid] if s > at]
        end = later[0] if later else math.inf
        after = [fr for fr in rows_of[pid] if at < fr <= end]
        # The new track's rows may carry the old id while provisional: the exit is the run
        # of rows before the last one that reaches the merge.
        upto = [fr for fr in rows_of[pid] if fr <= at]
        i = len(upto) - 1
        while i > 0 and upto[i] - upto[i - 1] <= 3:
            i -= 1
        runs = segments(upto[:i], 3)
        before = runs[-1] if runs else []
        tb, ta = majority(pid, before), majority(pid, after)
        if ta is None or tb is None:
            continue
        gap_s = (upto[i] - before[-1]) / fps if before and upto else float("nan")
        if tb == ta:
            right += 1
        else:
            wrong.append((at, pid, m["new_id"], tb, ta, gap_s))
    merged = {m["new_id"] for m in merges}
    first_seen: dict[int, list[tuple[int, int]]] = collections.defaultdict(list)
    for (fr, pid), t in truth.items():
        first_seen[t].append((fr, pid))
    new_right, missed = 0, []
    for pid, frames in rows_of.items():
        if pid in merged:
            continue
        first = splits[pid]
        own = [fr for fr in frames if not first or fr <= first[0]]
        t = majority(pid, own)
        if t is None:
            continue
        start = frames[0]
        earlier = [fr for fr, other in first_seen[t] if fr < start and other != pid]
        if earlier:
            missed.append((start, pid, t, (start - max(earlier)) / fps))
        else:
            new_right += 1
    print(f"links: {right} right, {len(wrong)} wrong; new objects: {new_right} right, "
          f"{len(missed)} missed links ({fps:.1f} fps)")
    for at, pid, new, tb, ta, gap in wrong:
        print(f"  wrong link at frame {at}: track {new} (true {ta}) into {pid} "
              f"(true {tb}), gap {gap:.0f} s")
    for start, pid, t, gap in sorted(missed):
        print(f"  missed link at frame {start}: track {pid} (true {t}) seen under another id "
              f"{gap:.0f} s before")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("size", help="physical size separability of the objects of one class")
    s.add_argument("gt_dir")
    s.add_argument("det")
    s.add_argument("--object-class", default="swimmer")
    s.set_defaults(func=cmd_size)
    p = sub.add_parser("perfect-reid", help="relabel an online run as if every ReID were right")
    p.add_argument("gt_dir")
    p.add_argument("out_dir")
    p.add_argument("relabelled")
    p.set_defaults(func=cmd_perfect_reid)
    d = sub.add_parser("decisions", help="classify an online run's ReID decisions")
    d.add_argument("gt_dir")
    d.add_argument("out_dir")
    d.add_argument("--results", help="the results file, when moved out of OUT_DIR")
    d.set_defaults(func=cmd_decisions)
    args = ap.parse_args()
    try:
        args.func(args)
    except OSError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
