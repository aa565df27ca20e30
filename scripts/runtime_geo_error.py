#!/usr/bin/env python3
"""Geolocation error of mgmot's MGMOT_TRACK messages against the simulator's ground truth.

For each geolocated MGMOT_TRACK (JSON lines from runtime_mavlink_tap.py), the ground-truth
objects of the same class in the frame nearest its time (world.csv of `mgmot-sim detections` /
`run --truth-out`) are searched and the distance to the nearest one is the error. Prints JSON
with count, median, p95 and max error in metres.

Usage: runtime_geo_error.py msgs.jsonl world.csv [--boot-time-s 120]
"""
import argparse
import csv
import json
import math
import statistics

CLASSES = {1: "swimmer", 2: "boat", 3: "jetski", 4: "life_saving_appliance", 5: "buoy"}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("messages")
    ap.add_argument("world_csv")
    ap.add_argument("--boot-time-s", type=float, default=120.0,
                    help="the scenario's telemetry.boot_time_s (autopilot clock at sim time 0)")
    args = ap.parse_args()
    truth = {}
    with open(args.world_csv) as f:
        for r in csv.DictReader(f):
            truth.setdefault(round(float(r["time_s"]) * 1000), []).append(r)
    times = sorted(truth)
    errors = []
    for line in open(args.messages):
        m = json.loads(line)
        if m.get("mavpackettype") != "MGMOT_TRACK" or not (m["flags"] & 1):
            continue
        t_ms = round((m["time_usec"] / 1e6 - args.boot_time_s) * 1000)
        nearest = min(times, key=lambda t: abs(t - t_ms))
        if abs(nearest - t_ms) > 20:
            continue
        lat, lon = m["lat"] * 1e-7, m["lon"] * 1e-7
        cls = CLASSES.get(m["object_class"])
        best = None
        for r in truth[nearest]:
            if r["class"] != cls:
                continue
            dn = (float(r["lat_deg"]) - lat) * 111_320.0
            de = (float(r["lon_deg"]) - lon) * 111_320.0 * math.cos(math.radians(lat))
            d = math.hypot(dn, de)
            best = d if best is None else min(best, d)
        if best is not None:
            errors.append(best)
    if not errors:
        print(json.dumps({"count": 0}))
        return
    errors.sort()
    print(json.dumps({
        "count": len(errors),
        "median_m": round(statistics.median(errors), 3),
        "p95_m": round(errors[min(len(errors) - 1, int(0.95 * len(errors)))], 3),
        "max_m": round(errors[-1], 3),
    }))


if __name__ == "__main__":
    main()
