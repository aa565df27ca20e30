#!/usr/bin/env python3
"""The two-drone SITL bench's fused picture against the truth (scripts/bench_sitl_fleet.sh).

Reads OUT/d1 and OUT/d2 (each a bench_sitl.sh output folder: its router tap's tlog, its
renderer's truth) and OUT/ground/fleet.jsonl (the shared mgmot ground's recording), and prints:

- each drone's MGMOT_TRACK against the truth (tracked, geolocated, not provisional);
- the fused picture against the truth: every tracked fused track matched to the nearest object
  within the gate at that moment; fused ids per object over the objects both drones reported
  (each fused id counted for the object it matched most often, as core's fuse::score);
- the position error where fusion has two drones to fuse: the picture updates at which both
  drones had reported that object within the 0.5 s before; the fused track and each drone's
  latest report (what that drone alone would show) against the truth at that update.

Both renderers place the one scenario around the same home, so each object has one id in
both truths; a picture's UTC time is mapped onto each drone's scenario clock through that
drone's SYSTEM_TIME and camera stamps, and the object's state is read from whichever drone's
truth has it then. Writes OUT/fleet_report.json.

Usage: bench_sitl_fleet_report.py OUT_DIR
"""
import bisect
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_sitl_report as bench  # noqa: E402
from runtime_mavlink_tap import load_dialect  # noqa: E402

PROVISIONAL = 4
PAIR_S = 0.5


def drone(dialect, out, sysid):
    """One drone's view: its truth, its matched MGMOT_TRACK records and its UTC mapping."""
    mgmot, autopilot = (sysid, 191), (sysid, 1)
    router = bench.read_tlog(dialect, os.path.join(out, "gcs_router.tlog"))
    truth = bench.load_truth(out)
    if truth is None:
        sys.exit("fleet report: %s has no truth (truth/camera.csv, truth/world.csv)" % out)
    tracks = [(t, 0, m) for t, m in router
              if bench.sender(m) == mgmot and m.get_type() == "MGMOT_TRACK" and m.state == 0
              and m.flags & bench.GEO_VALID and not m.flags & PROVISIONAL]
    recs = bench.check_tracks(truth, tracks)
    for rec, (_, _, m) in zip(recs, tracks):
        rec["lat"], rec["lon"] = m.lat * 1e-7, m.lon * 1e-7
    recs = [r for r in recs if r.get("matched")]
    utc = sorted((m.time_unix_usec, m.time_boot_ms * 1000) for t, m in router
                 if m.get_type() == "SYSTEM_TIME" and bench.sender(m) == autopilot and m.time_unix_usec > 0)
    return {"truth": truth, "recs": recs, "utc": utc, "utc_keys": [u[0] for u in utc],
            "objects": {r["object_id"] for r in recs}}


def scenario_t(d, unix_ms):
    """The drone's scenario time at UTC `unix_ms` (its nearest SYSTEM_TIME within 5 s)."""
    j = bisect.bisect_left(d["utc_keys"], unix_ms * 1000)
    near = [d["utc"][k] for k in (j - 1, j) if 0 <= k < len(d["utc"])]
    if not near:
        return None
    u, boot_us = min(near, key=lambda x: abs(x[0] - unix_ms * 1000))
    if abs(u - unix_ms * 1000) > 5_000_000:
        return None
    return bench.scenario_time(d["truth"]["boots"][0], boot_us + unix_ms * 1000 - u)


def truth_at(drones, unix_ms):
    """Every object's (north, east, class) at UTC `unix_ms`, from whichever truth has it."""
    states = {}
    for d in drones:
        t = scenario_t(d, unix_ms)
        if t is None:
            continue
        for oid, obj in d["truth"]["objects"].items():
            if oid in states:
                continue
            st = bench.object_state(obj, t)
            if st is not None:
                states[oid] = st
    return states


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = sys.argv[1]
    dialect = load_dialect()
    drones = [drone(dialect, os.path.join(out, "d%d" % k), k) for k in (1, 2)]
    report = {"drones": {}}
    print("\n==== SITL fleet report (%s)" % out)
    print("\n-- each drone's MGMOT_TRACK against the truth (tracked, geolocated, not provisional)")
    for k, d in enumerate(drones, 1):
        err = [r["error_m"] for r in d["recs"]]
        fig = {"matched": len(err), "objects": len(d["objects"]),
               "track_ids": len({r["track_id"] for r in d["recs"]}),
               "error_median_m": round(bench.pct(err, 0.5), 2) if err else None,
               "error_p95_m": round(bench.pct(err, 0.95), 2) if err else None}
        print("   drone %d: %s" % (k, json.dumps(fig)))
        report["drones"][k] = fig
    both = drones[0]["objects"] & drones[1]["objects"]
    print("   objects reported by both drones: %d (drone 1: %d, drone 2: %d)"
          % (len(both), len(drones[0]["objects"]), len(drones[1]["objects"])))

    rec_path = os.path.join(out, "ground", "fleet.jsonl")
    if not os.path.exists(rec_path):
        sys.exit("fleet report: no ground recording %s" % rec_path)
    lines = [json.loads(x) for x in open(rec_path) if x.strip()][1:]
    matched_to, fused_ids, classes = {}, set(), {"right": 0, "wrong": 0}
    errors, paired, unmatched, untimed = [], [], 0, 0
    for p in lines:
        tracks = [f for f in p.get("features", []) if f["properties"].get("kind") == "track"]
        fused_ids.update(f["properties"]["fused_id"] for f in tracks)
        tracked = [f for f in tracks if f["properties"].get("state") == "tracked"]
        if not tracked:
            continue
        unix_ms = p["properties"]["time_unix_ms"]
        states = truth_at(drones, unix_ms)
        if not states:
            untimed += len(tracked)
            continue
        for f in tracked:
            lon, lat = f["geometry"]["coordinates"][:2]
            best = min(((bench.distance_to_state(lat, lon, st), oid, st[3]) for oid, st in states.items()), default=None)
            if best is None or best[0] > bench.GATE_M:
                unmatched += 1
                continue
            err, oid, cls = best
            errors.append(err)
            per = matched_to.setdefault(f["properties"]["fused_id"], {})
            per[oid] = per.get(oid, 0) + 1
            same = f["properties"].get("class_id") == bench.CLASS_IDS.get(cls)
            classes["right" if same else "wrong"] += 1
            # What each drone alone showed at this update: its latest report of this object,
            # if that arrived within PAIR_S before, against the truth at this update (as the
            # fused track is scored).
            near = []
            u = unix_ms / 1000
            for d in drones:
                cand = [r for r in d["recs"] if r["object_id"] == oid and 0 <= u - r["arrival"] <= PAIR_S]
                if cand:
                    last = max(cand, key=lambda r: r["arrival"])
                    near.append(bench.distance_to_state(last["lat"], last["lon"], states[oid]))
            if len(near) == 2:
                paired.append((err, near[0], near[1]))
    identity = bench.identities(matched_to)
    per_both = [len(identity.get(o, set())) for o in both if o in identity]
    fused = {
        "pictures": len(lines), "fused_ids": len(fused_ids), "tracked_samples_matched": len(errors),
        "unmatched": unmatched, "untimed": untimed,
        "error_median_m": round(bench.pct(errors, 0.5), 2) if errors else None,
        "error_p95_m": round(bench.pct(errors, 0.95), 2) if errors else None,
        "objects_seen_by_both": len(both),
        "fused_ids_per_object_seen_by_both": round(sum(per_both) / len(per_both), 3) if per_both else None,
        "max_ids_per_object": max(per_both) if per_both else None,
        "class": classes,
    }
    print("\n-- the fleet's fused picture (mgmot ground on both routers)")
    print("   %s" % json.dumps(fused))
    report["fused"] = fused
    if paired:
        cols = list(zip(*paired))
        fig = {"moments": len(paired)}
        for name, v in zip(("fused", "drone_1", "drone_2"), cols):
            fig[name] = [round(bench.pct(list(v), 0.5), 2), round(bench.pct(list(v), 0.95), 2)]
        print("   both at once (%d moments), median / p95 m: fused %s, drone 1 %s, drone 2 %s"
              % (len(paired), fig["fused"], fig["drone_1"], fig["drone_2"]))
        report["both_at_once"] = fig
    else:
        print("   no moment with both drones' reports of one object within %.1f s" % PAIR_S)
    json.dump(report, open(os.path.join(out, "fleet_report.json"), "w"), indent=1)


if __name__ == "__main__":
    main()
