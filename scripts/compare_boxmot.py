#!/usr/bin/env python3
"""BoxMOT side by side with mgmot, on the same simulated detections (driven by
scripts/compare_boxmot.sh).

  compare_boxmot.py track TRACKER CONF DET.txt SEQINFO.ini OUT.txt [FRAMES_DIR]
      runs one BoxMOT 25.0.0 tracker (botsort, bytetrack, ocsort) on a MOTChallenge
      detection file; CONF is 'paper' (the paper's / mgmot's BoT-SORT thresholds) or
      'default' (BoxMOT's own). With FRAMES_DIR (NNNNNN.jpg) BoT-SORT compensates camera
      motion with sparse optical flow; without it no tracker gets images (a blank frame).
  compare_boxmot.py table OUT_DIR
      prints the Markdown table from OUT_DIR/<scenario>/<seed>/*.json (`mgmot eval --json`).

BoxMOT's appearance models need weights downloaded at run time, which this project cannot
do: BoT-SORT runs without embeddings (as the issue's own comparison did).
"""
import collections
import configparser
import glob
import json
import os
import sys
import time

BOXMOT_RUNS = [(t, c) for t in ("botsort", "bytetrack", "ocsort") for c in ("paper", "default")]
MGMOT_RUNS = ["online", "online_withheld", "offline"]


def track(name, conf, det_path, seqinfo, out_path, frames=None):
    import numpy as np

    ini = configparser.ConfigParser()
    if not ini.read(seqinfo):
        sys.exit(f"compare_boxmot: cannot read {seqinfo}")
    s = ini["Sequence"]
    width, height, n_frames, fps = (int(s[k]) for k in ("imWidth", "imHeight", "seqLength", "frameRate"))
    dets = collections.defaultdict(list)
    with open(det_path) as f:
        for line in f:
            v = line.strip().split(",")
            if len(v) < 8:
                continue
            x, y, w, h, score = map(float, v[2:7])
            dets[int(float(v[0]))].append([x, y, x + w, y + h, score, max(int(float(v[7])), 0)])
    from boxmot import BotSort, ByteTrack, OcSort

    paper = conf == "paper"
    if name == "botsort":
        kw = dict(track_high_thresh=0.5, track_low_thresh=0.1, new_track_thresh=0.2, track_buffer=100,
                  match_thresh=0.9, second_match_thresh=0.5, unconfirmed_match_thresh=0.7) if paper else {}
        tracker = BotSort(use_embeddings=False, device="cpu", half=False, frame_rate=fps,
                          use_cmc=frames is not None, cmc_method="sof", **kw)
    elif name == "bytetrack":
        kw = dict(min_conf=0.1, track_thresh=0.5, match_thresh=0.9, track_buffer=100) if paper else {}
        tracker = ByteTrack(frame_rate=fps, **kw)
    elif name == "ocsort":
        kw = dict(min_conf=0.1, det_thresh=0.2, max_age=100, use_byte=True) if paper else {}
        tracker = OcSort(**kw)
    else:
        sys.exit(f"compare_boxmot: unknown tracker {name}")
    blank = np.zeros((height, width, 3), np.uint8)
    if frames is not None:
        import cv2
    start = time.perf_counter()
    with open(out_path, "w") as out:
        for fr in range(1, n_frames + 1):
            img = blank
            if frames is not None:
                img = cv2.imread(os.path.join(frames, f"{fr:06d}.jpg"))
                if img is None:
                    sys.exit(f"compare_boxmot: frame {fr} missing in {frames}")
            d = np.array(dets.get(fr, []), dtype=np.float32).reshape(-1, 6)
            for row in tracker.update(d, img):
                x1, y1, x2, y2, tid, score = (float(v) for v in row[:6])
                out.write(f"{fr},{int(tid)},{x1:.2f},{y1:.2f},{x2 - x1:.2f},{y2 - y1:.2f},{score:.4f},-1,-1,-1\n")
    dt = time.perf_counter() - start
    print(f"{name} {conf}: {n_frames} frames, {1000 * dt / n_frames:.2f} ms/frame", file=sys.stderr)


def table(out_dir):
    rows = []
    summary = collections.defaultdict(lambda: collections.defaultdict(list))
    for sc_dir in sorted(glob.glob(os.path.join(out_dir, "*", ""))):
        sc = os.path.basename(os.path.dirname(sc_dir))
        for seed_dir in sorted(glob.glob(os.path.join(sc_dir, "*", ""))):
            seed = os.path.basename(os.path.dirname(seed_dir))

            def load(run):
                p = os.path.join(seed_dir, run + ".json")
                return json.load(open(p)) if os.path.exists(p) else None

            box = {f"{t}-{c}": load(f"boxmot_{t}_{c}") for t, c in BOXMOT_RUNS}
            box = {k: v for k, v in box.items() if v}
            mg = {r: load(r) for r in MGMOT_RUNS}
            if not box or not all(mg.values()):
                continue
            frames = os.path.exists(os.path.join(seed_dir, "with_frames"))
            best_h = max(box, key=lambda k: box[k]["HOTA"])
            best_i = max(box, key=lambda k: box[k]["IDF1"])
            rows.append((sc, seed, frames, box, best_h, best_i, mg))
            for r in MGMOT_RUNS:
                summary[sc][r].append((mg[r]["HOTA"] - box[best_h]["HOTA"], mg[r]["IDF1"] - box[best_i]["IDF1"]))
    print("| scenario | seed | CMC | BoxMOT best HOTA (tracker) | BoxMOT best IDF1 (tracker) "
          "| mgmot online HOTA / IDF1 | online withheld | offline |")
    print("|---|---|---|---|---|---|---|---|")
    for sc, seed, frames, box, bh, bi, mg in rows:
        cells = [f"{mg[r]['HOTA']:.3f} / {mg[r]['IDF1']:.3f}" for r in MGMOT_RUNS]
        print(f"| {sc} | {seed} | {'sof' if frames else 'none'} | {box[bh]['HOTA']:.3f} ({bh}) "
              f"| {box[bi]['IDF1']:.3f} ({bi}) | " + " | ".join(cells) + " |")
    print()
    print("mgmot minus BoxMOT's best (per scenario and seed, best tracker chosen separately for HOTA "
          "and IDF1): mean HOTA / mean IDF1, [worst seed]")
    print()
    print("| scenario | online | online withheld | offline |")
    print("|---|---|---|---|")
    for sc in sorted(summary):
        cells = []
        for r in MGMOT_RUNS:
            d = summary[sc][r]
            mh = sum(x for x, _ in d) / len(d)
            mi = sum(y for _, y in d) / len(d)
            cells.append(f"{mh:+.3f} / {mi:+.3f} [{min(x for x, _ in d):+.3f} / {min(y for _, y in d):+.3f}]")
        print(f"| {sc} | " + " | ".join(cells) + " |")


def main():
    if len(sys.argv) >= 7 and sys.argv[1] == "track":
        track(*sys.argv[2:7], frames=sys.argv[7] if len(sys.argv) > 7 else None)
    elif len(sys.argv) == 3 and sys.argv[1] == "table":
        table(sys.argv[2])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
