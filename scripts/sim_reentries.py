#!/usr/bin/env python3
"""Re-entries of the true objects in a simulated sequence's ground truth.

For every true id in ``gt/gt.txt`` (MOTChallenge, ``frame,id,x,y,w,h,...``; the frames in
which the object is visible), a *re-entry* is a gap between two consecutive frames in which
it is visible that is longer than ``--min-gap-s`` (2 s), converted to seconds with the
``frameRate`` of ``seqinfo.ini``. This is what long-gap re-identification faces: the object
left the camera's view and came back.

Prints, per sequence folder: frames (``seqLength``), true objects (ids seen at least once),
re-entries (number of such gaps), their median and max length in seconds, and how many
exceed ``--long-s`` (60 s). ``--json`` prints the same as JSON.

Usage (the folder is what ``mgmot-sim detections ... --gt-dir`` or ``render -o`` writes):

    mgmot-sim detections -s lawnmower_search -o /tmp/x/lawnmower_search.json \\
        --gt-dir /tmp/x/lawnmower_search_gt
    python3 scripts/sim_reentries.py /tmp/x/lawnmower_search_gt [more folders ...]

Standard library only.
"""

from __future__ import annotations

import argparse
import configparser
import json
import statistics
import sys
from collections import defaultdict
from pathlib import Path


def read_seqinfo(folder: Path) -> tuple[float, int]:
    """(frame rate, sequence length) from ``seqinfo.ini``."""
    ini = configparser.ConfigParser()
    ini.read(folder / "seqinfo.ini")
    seq = ini["Sequence"]
    return float(seq["frameRate"]), int(seq["seqLength"])


def reentries(folder: Path, min_gap_s: float, long_s: float) -> dict:
    """The statistics of one sequence folder."""
    fps, frames = read_seqinfo(folder)
    seen: dict[int, set[int]] = defaultdict(set)
    with open(folder / "gt" / "gt.txt", encoding="utf-8") as f:
        for line in f:
            parts = line.strip().split(",")
            if len(parts) < 2:
                continue
            seen[int(parts[1])].add(int(parts[0]))
    gaps = []
    for frames_seen in seen.values():
        ordered = sorted(frames_seen)
        for a, b in zip(ordered, ordered[1:]):
            # b - a frame intervals between two visible frames; a gap of one interval is
            # continuous visibility.
            gap_s = (b - a) / fps
            if gap_s > min_gap_s:
                gaps.append(gap_s)
    return {
        "sequence": folder.name,
        "fps": fps,
        "frames": frames,
        "objects": len(seen),
        "reentries": len(gaps),
        "median_gap_s": round(statistics.median(gaps), 1) if gaps else None,
        "max_gap_s": round(max(gaps), 1) if gaps else None,
        f"over_{long_s:g}_s": sum(g > long_s for g in gaps),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+", type=Path, help="sequence folders (with gt/gt.txt)")
    ap.add_argument("--min-gap-s", type=float, default=2.0, help="shortest gap counted (2)")
    ap.add_argument("--long-s", type=float, default=60.0, help="long-gap threshold (60)")
    ap.add_argument("--json", action="store_true", help="JSON instead of a table")
    args = ap.parse_args()
    rows = [reentries(f, args.min_gap_s, args.long_s) for f in args.folders]
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    long_key = f"over_{args.long_s:g}_s"
    print(f"| sequence | frames | objects | re-entries | median gap s | max gap s | > {args.long_s:g} s |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['sequence']} | {r['frames']} | {r['objects']} | {r['reentries']} | "
            f"{r['median_gap_s']} | {r['max_gap_s']} | {r[long_key]} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
