#!/usr/bin/env python3
"""Write a large MOTChallenge case for timing `mgmot eval` (issue target:
10,000 frames x 30 objects in <= 2 s).

    python3 scripts/eval_make_large_case.py OUT_DIR [--frames 10000] [--objects 30]
    time target/release/mgmot eval --gt OUT_DIR/gt.txt --pred OUT_DIR/pred.txt --json

Ground truth: objects drifting over a 1920x1080 image; results: noisy boxes,
5% misses, occasional id switches, one false positive per frame.
"""
import argparse
import os
import random


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out_dir")
    ap.add_argument("--frames", type=int, default=10000)
    ap.add_argument("--objects", type=int, default=30)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rng = random.Random(args.seed)
    os.makedirs(args.out_dir, exist_ok=True)
    pred_ids = list(range(1, args.objects + 1))
    next_id = args.objects + 1
    with open(os.path.join(args.out_dir, "gt.txt"), "w") as gt, \
            open(os.path.join(args.out_dir, "pred.txt"), "w") as pred:
        for f in range(1, args.frames + 1):
            for o in range(args.objects):
                x = (o * 60.0 + f * 0.3 * (1 + o / 30.0)) % 1800.0
                y = (o * 31.0 + f * 0.1) % 1000.0
                w, h = 40.0 + o, 60.0
                gt.write("%d,%d,%.2f,%.2f,%.2f,%.2f,1,1,1\n" % (f, o + 1, x, y, w, h))
                if rng.random() < 0.05:
                    continue
                if rng.random() < 0.002:
                    pred_ids[o] = next_id
                    next_id += 1
                pred.write("%d,%d,%.2f,%.2f,%.2f,%.2f,0.9,-1,-1,-1\n"
                           % (f, pred_ids[o], x + rng.uniform(-2, 2), y + rng.uniform(-2, 2), w, h))
            pred.write("%d,%d,%.2f,%.2f,50,50,0.3,-1,-1,-1\n"
                       % (f, 100000 + f, rng.uniform(100, 1700), rng.uniform(100, 900)))


if __name__ == "__main__":
    main()
