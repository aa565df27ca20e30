#!/usr/bin/env python3
"""The SITL bench's report (scripts/bench_sitl.sh): reads the two ground stations' tlogs, the
renderer's truth and track report and mgmot's stats from the bench's output folder and prints:

1. the autopilot's streams on the companion link (router tap) per type and rate, and the
   answers to the SET_MESSAGE_INTERVAL requests;
2. TIMESYNC: mgmot's requests, the autopilot's answers, offset and round trip;
3. the camera pose the renderer used (the telemetry) against SITL's own state (SIMSTATE);
4. the geolocation error of every MGMOT_TRACK against the truth (mgmot-sim follow's check);
5. which of mgmot's messages reached each ground station: through the router (a direct path)
   and through the autopilot's telemetry radio alone;
6. MGMOT_TRACK against the truth, computed here from truth/world.csv: geolocation error and
   velocity error (vel_n, vel_e against the object's motion in the truth), for the whole run,
   or BEFORE and AFTER the autopilot's reboot when the ground station rebooted it
   (bench_sitl_fly.py --reboot-at), with the time from the first pose of the new boot to the
   first geolocated MGMOT_TRACK, and mgmot's WARN/ERROR lines and telemetry counters;
7. mgmot ground on both paths (router: MGMOT_TRACK; SITL's second radio: the STATUSTEXT digest
   alone): what it heard, and its fused picture against the truth (each tracked fused track
   matched to the nearest object within the gate at that moment; fused ids per object).

Usage: bench_sitl_report.py OUT_DIR [--system-id N]   (the vehicle's system id, 1 by default)
"""
import argparse
import csv
import json
import math
import os
import statistics
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from runtime_mavlink_tap import load_dialect  # noqa: E402

# The vehicle's system id (--system-id, as bench_sitl.sh --instance): the autopilot is
# (SYSID, 1), mgmot (SYSID, 191).
MGMOT = (1, 191)
AUTOPILOT = (1, 1)


def read_tlog(dialect, path):
    """(UNIX time s, message) of every packet in a tlog."""
    mav = dialect.MAVLink(None)
    mav.robust_parsing = True
    out = []
    if not os.path.exists(path):
        return out
    data = open(path, "rb").read()
    i = 0
    while i + 9 <= len(data):
        t = struct.unpack(">Q", data[i:i + 8])[0] / 1e6
        i += 8
        magic = data[i]
        if magic == 0xFD:
            n = 12 + data[i + 1] + (13 if data[i + 2] & 1 else 0)
        elif magic == 0xFE:
            n = 8 + data[i + 1]
        else:
            break
        for m in mav.parse_buffer(data[i:i + n]) or []:
            if m.get_type() != "BAD_DATA":
                out.append((t, m))
        i += n
    return out


def sender(m):
    return (m.get_srcSystem(), m.get_srcComponent())


def rate(times):
    return (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 and times[-1] > times[0] else 0.0


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")


GEO_VALID = 1
GATE_M = 20.0  # as mgmot-sim's track monitor (sim/src/monitor.rs ASSOCIATION_GATE_M)


def m_per_deg(lat_deg):
    """Metres per degree of latitude and of longitude (WGS84) at `lat_deg`."""
    p = math.radians(lat_deg)
    return (111132.92 - 559.82 * math.cos(2 * p) + 1.175 * math.cos(4 * p),
            111412.84 * math.cos(p) - 93.5 * math.cos(3 * p))


def load_truth(out):
    """Camera frames split into autopilot boots (the frame stamp, on the autopilot clock, goes
    back at a reboot) and each object's visible samples from truth/world.csv."""
    cam_path = os.path.join(out, "truth", "camera.csv")
    world_path = os.path.join(out, "truth", "world.csv")
    if not (os.path.exists(cam_path) and os.path.exists(world_path)):
        return None
    boots = [[]]  # per boot: (frame_stamp_us, time_s, frame)
    last = None
    for r in csv.DictReader(open(cam_path)):
        stamp = int(r["frame_stamp_us"])
        if last is not None and stamp < last - 1_000_000:
            boots.append([])
        last = stamp
        boots[-1].append((stamp, float(r["time_s"]), int(r["frame"])))
    for b in boots:
        b.sort()
    objects = {}
    for r in csv.DictReader(open(world_path)):
        objects.setdefault(int(r["id"]), []).append(
            (float(r["time_s"]), float(r["north_m"]), float(r["east_m"]), float(r["lat_deg"]), float(r["lon_deg"]), r["class"]))
    for v in objects.values():
        v.sort()
    return {"boots": [([x[0] for x in b], b) for b in boots],
            "objects": {k: ([x[0] for x in v], v) for k, v in objects.items()}}


def scenario_time(boot, time_usec):
    """The scenario time of a capture stamp on a boot's clock (nearest frame within 0.1 s)."""
    import bisect
    stamps, boot = boot
    j = bisect.bisect_left(stamps, time_usec)
    best = None
    for k in (j - 1, j):
        if 0 <= k < len(boot) and (best is None or abs(boot[k][0] - time_usec) < abs(best[0] - time_usec)):
            best = boot[k]
    if best is None or abs(best[0] - time_usec) > 100_000:
        return None
    return best[1] + (time_usec - best[0]) / 1e6


def object_state(obj, t):
    """(north, east, vel_n, vel_e, class) of an object at scenario time t from its visible
    samples: interpolated (or extrapolated up to 2 s), the velocity a least-squares fit over
    +-1 s (+-3 s when it is seen too briefly); None when not seen within 2 s."""
    import bisect
    ts, samples = obj
    j = bisect.bisect_left(ts, t)
    near = [samples[k] for k in (j - 1, j) if 0 <= k < len(samples)]
    if not near or min(abs(x[0] - t) for x in near) > 2.0:
        return None
    vel = None
    for w in (1.0, 3.0):
        win = samples[bisect.bisect_left(ts, t - w):bisect.bisect_right(ts, t + w)]
        if len(win) >= 3 and win[-1][0] - win[0][0] >= 0.5:
            mt = sum(x[0] for x in win) / len(win)
            den = sum((x[0] - mt) ** 2 for x in win)
            vel = tuple(sum((x[0] - mt) * x[i] for x in win) / den for i in (1, 2))
            break
    if len(near) == 2 and near[1][0] > near[0][0] and near[1][0] - near[0][0] <= 0.5:
        a, b = near
        f = (t - a[0]) / (b[0] - a[0])
        n, e = a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f
    else:
        a = min(near, key=lambda x: abs(x[0] - t))
        dt = t - a[0]
        n, e = a[1] + (vel[0] * dt if vel else 0.0), a[2] + (vel[1] * dt if vel else 0.0)
    return n, e, vel, near[0][5], near[0]


def distance_to_state(lat, lon, st):
    """Distance (m) from (lat, lon) to an object state of object_state: the point is put in
    the scenario's north/east through the state's own sample (flat earth over metres)."""
    n, e, _, _, ref = st
    mlat, mlon = m_per_deg(ref[3])
    return math.hypot(ref[1] + (lat - ref[3]) * mlat - n, ref[2] + (lon - ref[4]) * mlon - e)


def identities(matched_to):
    """Object id -> the fused ids whose identity it is: each fused id is the object it matched
    most often (as core's fuse::score). `matched_to`: fused id -> object id -> samples."""
    identity = {}
    for fid, per in matched_to.items():
        identity.setdefault(max(per, key=per.get), set()).add(fid)
    return identity


def check_tracks(truth, tracks):
    """Each (arrival, boot, MGMOT_TRACK) against the truth: a dict per message."""
    out = []
    for arrival, boot, m in tracks:
        rec = {"arrival": arrival, "boot": boot, "track_id": m.track_id, "geo": bool(m.flags & GEO_VALID),
               "state": m.state, "speed": math.hypot(m.vel_n, m.vel_e) if m.flags & GEO_VALID else None}
        out.append(rec)
        if not rec["geo"]:
            continue
        t = scenario_time(truth["boots"][boot], m.time_usec) if boot < len(truth["boots"]) else None
        rec["t_s"] = t
        if t is None:
            continue
        lat, lon = m.lat * 1e-7, m.lon * 1e-7
        best = None
        for oid, samples in truth["objects"].items():
            st = object_state(samples, t)
            if st is None:
                continue
            d = distance_to_state(lat, lon, st)
            if best is None or d < best[0]:
                best = (d, oid, st[2], st[3])
        if best is None or best[0] > GATE_M:
            rec["matched"] = False
            rec["why"] = "no_truth_within_2s" if best is None else "beyond_gate"
            continue
        rec.update(matched=True, error_m=best[0], object_id=best[1], cls=best[3])
        if best[2] is not None:
            rec["vel_error"] = math.hypot(m.vel_n - best[2][0], m.vel_e - best[2][1])
            rec["true_speed"] = math.hypot(*best[2])
    return out


def segment_figures(recs):
    geo = [r for r in recs if r["geo"]]
    matched = [r for r in geo if r.get("matched")]
    err = [r["error_m"] for r in matched]
    vel = [r["vel_error"] for r in matched if "vel_error" in r]
    vel_sw = [r["vel_error"] for r in matched if "vel_error" in r and r["cls"] == "swimmer"]
    speeds = [r["speed"] for r in geo]
    f = lambda v, q: round(pct(v, q), 3) if v else None  # noqa: E731
    return {
        "messages": len(recs), "geolocated": len(geo), "matched": len(matched),
        "lost_state": sum(1 for r in recs if r["state"] == 1),
        "unmatched_no_truth_within_2s": sum(1 for r in geo if r.get("why") == "no_truth_within_2s"),
        "unmatched_beyond_20m": sum(1 for r in geo if r.get("why") == "beyond_gate"),
        "no_frame_for_stamp": sum(1 for r in geo if r.get("t_s") is None),
        "track_ids": len({r["track_id"] for r in recs}),
        "geo_error_median_m": f(err, 0.5), "geo_error_p95_m": f(err, 0.95), "geo_error_max_m": round(max(err), 3) if err else None,
        "vel_error_median_mps": f(vel, 0.5), "vel_error_p95_mps": f(vel, 0.95), "vel_error_max_mps": round(max(vel), 3) if vel else None,
        "vel_error_swimmers_median_mps": f(vel_sw, 0.5), "vel_error_swimmers_p95_mps": f(vel_sw, 0.95),
        "reported_speed_median_mps": f(speeds, 0.5), "reported_speed_max_mps": round(max(speeds), 3) if speeds else None,
        "true_speed_median_mps": f([r["true_speed"] for r in matched if "true_speed" in r], 0.5),
    }


def reboot_section(out, dialect, router, report):
    print("\n-- 6. MGMOT_TRACK against the truth (truth/world.csv): geolocation and velocity error")
    summary_path = os.path.join(out, "gcs_summary.json")
    summary = json.load(open(summary_path)) if os.path.exists(summary_path) else {}
    rb = summary.get("reboot")
    truth = load_truth(out)
    if truth is None:
        print("   no truth/camera.csv or truth/world.csv")
        return
    # Autopilot boots as the router tap saw them: a pose whose time_boot_ms goes back.
    poses = [(t, m) for t, m in router if sender(m) == AUTOPILOT and m.get_type() in ("GLOBAL_POSITION_INT", "ATTITUDE")]
    boot_starts = []  # (arrival of the first pose of the boot, its time_boot_ms)
    last_ms = None
    for t, m in poses:
        if last_ms is not None and m.time_boot_ms + 1000 < last_ms:
            boot_starts.append((t, m.time_boot_ms))
        last_ms = m.time_boot_ms
    tracks = []
    for t, m in router:
        if sender(m) != MGMOT or m.get_type() != "MGMOT_TRACK":
            continue
        boot = sum(1 for b, _ in boot_starts if t >= b)
        # A message that arrives just after a reboot can describe a frame of the boot before.
        if boot > 0 and m.flags & GEO_VALID and boot < len(truth["boots"]) and \
                scenario_time(truth["boots"][boot], m.time_usec) is None and \
                scenario_time(truth["boots"][boot - 1], m.time_usec) is not None:
            boot -= 1
        tracks.append((t, boot, m))
    recs = check_tracks(truth, tracks)
    dry = bool(rb) and not boot_starts  # --reboot-dry-run: one boot, split at the "reboot" time
    for rec in recs:
        rec["seg"] = (1 if rec["arrival"] >= rb["requested_at"] else 0) if dry else rec["boot"]
    print("   %d camera frames in %d autopilot boot(s); %d MGMOT_TRACK at the router tap; %d reboot(s) seen there"
          % (sum(len(b[1]) for b in truth["boots"]), len(truth["boots"]), len(recs), len(boot_starts)))
    if rb:
        print("   reboot (%s) requested at %.3f (UNIX, companion clock), %.1f s after the ground station's start; COMMAND_ACK %s"
              % (rb.get("mode"), rb["requested_at"], rb["requested_at"] - summary.get("t0", rb["requested_at"]), rb.get("ack")))
    segments = [("BEFORE", 0), ("AFTER", 1)] if boot_starts or dry else [("ALL", 0)]
    report["segments"] = {}
    for name, seg in segments:
        fig = segment_figures([r for r in recs if r["seg"] == seg])
        report["segments"][name] = fig
        print("   %-6s %s" % (name, json.dumps(fig)))
    # Per boot: seconds from its first autopilot pose at the router tap to the first frame, the
    # first object in view (truth) and the first geolocated MGMOT_TRACK on that boot's clock.
    visible_ts = sorted(x for ts, _ in truth["objects"].values() for x in ts)
    first_pose_all = poses[0][0] if poses else None
    starts = ([(first_pose_all, poses[0][1].time_boot_ms)] if poses else []) + boot_starts
    report["boot_timing"] = {}
    for b, (first_pose_t, first_ms) in enumerate(starts):
        end_t = starts[b + 1][0] if b + 1 < len(starts) else float("inf")
        mine = [(t, m) for t, m in poses if first_pose_t <= t < end_t]
        valid_pos = next((t for t, m in mine if m.get_type() == "GLOBAL_POSITION_INT" and m.lat != 0), None)
        airborne = next((t for t, m in mine if m.get_type() == "GLOBAL_POSITION_INT" and m.relative_alt > 25000), None)
        # The boot's clock on the companion clock, from the poses' arrival (least delayed).
        offset = min(t - m.time_boot_ms / 1e3 for t, m in mine[:2000])
        frames = truth["boots"][b][1] if b < len(truth["boots"]) else []
        first_frame = frames[0][0] / 1e6 + offset if frames else None
        first_visible = None
        if frames:
            fv = next((x for x in visible_ts if frames[0][1] <= x <= frames[-1][1]), None)
            if fv is not None:
                first_visible = min(frames, key=lambda x: abs(x[1] - fv))[0] / 1e6 + offset
        geo = [r for r in recs if r["boot"] == b and r["geo"]]
        first_any = next((r["arrival"] for r in recs if r["boot"] == b), None)
        first_geo = geo[0]["arrival"] if geo else None
        first_tracked = next((r["arrival"] for r in geo if r["state"] == 0), None)
        first_matched = next((r["arrival"] for r in geo if r.get("matched")), None)
        # Per object: from its first frame in view on this boot to its first geolocated TRACKED
        # MGMOT_TRACK (matched to it).
        latency = {}
        for oid, (ts, samples) in truth["objects"].items():
            fv = next((x for x in ts if frames and frames[0][1] <= x <= frames[-1][1]), None)
            if fv is None:
                continue
            seen = min(frames, key=lambda x: abs(x[1] - fv))[0] / 1e6 + offset
            hit = next((r["arrival"] for r in geo if r.get("object_id") == oid and r["state"] == 0 and r["arrival"] >= seen), None)
            latency[oid] = round(hit - seen, 2) if hit is not None else None
        lat_v = sorted(v for v in latency.values() if v is not None)
        rel = lambda x: None if x is None else round(x - first_pose_t, 2)  # noqa: E731
        timing = {
            "first_pose_unix": round(first_pose_t, 3),
            "first_pose_time_boot_ms": first_ms,
            "s_reboot_request_to_first_pose": round(first_pose_t - rb["requested_at"], 2) if rb and b == 1 else None,
            "s_to_first_valid_position": rel(valid_pos),
            "s_to_first_frame_rendered": rel(first_frame),
            "s_to_airborne_25m": rel(airborne),
            "s_to_first_frame_with_an_object_in_view": rel(first_visible),
            "s_to_first_MGMOT_TRACK": rel(first_any),
            "s_to_first_geolocated_MGMOT_TRACK": rel(first_geo),
            "s_to_first_geolocated_TRACKED_MGMOT_TRACK": rel(first_tracked),
            "s_to_first_geolocated_matched_MGMOT_TRACK": rel(first_matched),
            "s_first_object_in_view_to_first_geolocated_TRACKED_track":
                round(first_tracked - first_visible, 2) if first_tracked is not None and first_visible is not None else None,
            "per_object_s_in_view_to_first_track": {"%d %s" % (k, truth["objects"][k][1][0][5]): v for k, v in sorted(latency.items())},
            "per_object_median_s": lat_v[len(lat_v) // 2] if lat_v else None,
        }
        name = "ALL" if not boot_starts else ("BEFORE" if b == 0 else "AFTER" if b == 1 else "AFTER%d" % b)
        report["boot_timing"][name] = timing
        print("   %-6s seconds from the boot's first autopilot pose (router tap): %s" % (name, json.dumps(timing)))
    # mgmot's log: WARN/ERROR lines before and after the reboot.
    import re
    log_path = os.path.join(out, "mgmot.log")
    if os.path.exists(log_path):
        from datetime import datetime, timezone
        split = rb["requested_at"] if rb else (boot_starts[0][0] if boot_starts else None)
        counts = {}
        for line in open(log_path, errors="replace"):
            line = re.sub(r"\x1b\[[0-9;]*m", "", line).rstrip()
            mt = re.match(r"^(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(?:\.\d+)?)Z\s+(WARN|ERROR)\s+(\S+?):?\s+(.*)$", line)
            if not mt:
                continue
            ts = datetime.fromisoformat(mt.group(1)[:26]).replace(tzinfo=timezone.utc).timestamp()
            seg = "ALL" if split is None else ("AFTER" if ts >= split else "BEFORE")
            msg = re.sub(r"\d+(\.\d+)?", "N", mt.group(4))[:110]
            key = (seg, mt.group(2), msg)
            counts[key] = counts.get(key, 0) + 1
        print("   mgmot.log WARN/ERROR lines (numbers masked as N), per segment (split at the reboot request):")
        for (seg, lvl, msg), n in sorted(counts.items(), key=lambda kv: (kv[0][0], -kv[1])):
            print("      %-6s %-5s x%-4d %s" % (seg, lvl, n, msg))
        report["log_warn_error"] = {"%s %s %s" % k: v for k, v in counts.items()}
    stats = os.path.join(out, "mgmot_stats.json")
    if os.path.exists(stats):
        st = json.load(open(stats))
        print("   mgmot stats: telemetry %s, clock_jumps %s, frames_without_pose %s, track_messages %s"
              % (st.get("telemetry"), st.get("clock_jumps"), st.get("frames_without_pose"), st.get("track_messages")))
        report["mgmot_telemetry"] = st.get("telemetry")
        report["mgmot_clock_jumps"] = st.get("clock_jumps")


# SeaDronesSee class ids of the truth's class names.
CLASS_IDS = {"swimmer": 1, "boat": 2, "jetski": 3, "life_saving_appliances": 4, "lifebuoy": 4, "buoy": 5}


def ground_section(out, router, report):
    """mgmot ground's recordings (OUT/ground/{router,radio}.jsonl) against the truth. The
    picture's time is UTC: mapped onto the autopilot's boot clock with its SYSTEM_TIME (router
    tap), then onto the scenario time with the renderer's frames."""
    import bisect
    print("\n-- 7. mgmot ground's fused picture against the truth")
    truth = load_truth(out)
    utc = []  # (unix_us, boot index, boot_us)
    boot, last = 0, None
    for _, m in router:
        if m.get_type() == "SYSTEM_TIME" and sender(m) == AUTOPILOT and m.time_unix_usec > 0:
            if last is not None and m.time_boot_ms + 1000 < last:
                boot += 1
            last = m.time_boot_ms
            utc.append((m.time_unix_usec, boot, m.time_boot_ms * 1000))
    utc.sort()
    keys = [u[0] for u in utc]

    def scenario_t(unix_ms):
        j = bisect.bisect_left(keys, unix_ms * 1000)
        near = [utc[k] for k in (j - 1, j) if 0 <= k < len(utc)]
        if not near or truth is None:
            return None
        u, b, boot_us = min(near, key=lambda x: abs(x[0] - unix_ms * 1000))
        if abs(u - unix_ms * 1000) > 5_000_000 or b >= len(truth["boots"]):
            return None
        return scenario_time(truth["boots"][b], boot_us + unix_ms * 1000 - u)

    report["ground"] = {}
    for name in ("router", "radio"):
        rec = os.path.join(out, "ground", name + ".jsonl")
        stats_path = os.path.join(out, "ground", name + "_stats.json")
        if not os.path.exists(rec):
            print("   %s: no recording (%s)" % (name, rec))
            continue
        stats = json.load(open(stats_path)) if os.path.exists(stats_path) else {}
        lines = [json.loads(x) for x in open(rec) if x.strip()][1:]
        errors, ids_of, classes = [], {}, {"right": 0, "wrong": 0}
        matched_to = {}  # fused id -> object id -> samples
        unmatched = untimed = 0
        fused_ids = set()
        for p in lines:
            tracks = [f for f in p.get("features", []) if f["properties"].get("kind") == "track"]
            fused_ids.update(f["properties"]["fused_id"] for f in tracks)
            tracked = [f for f in tracks if f["properties"].get("state") == "tracked"]
            if not tracked:
                continue
            t = scenario_t(p["properties"]["time_unix_ms"])
            if t is None:
                untimed += len(tracked)
                continue
            states = {oid: object_state(obj, t) for oid, obj in truth["objects"].items()}
            for f in tracked:
                lon, lat = f["geometry"]["coordinates"][:2]
                best = None
                for oid, st in states.items():
                    if st is None:
                        continue
                    d = distance_to_state(lat, lon, st)
                    if d <= GATE_M and (best is None or d < best[0]):
                        best = (d, oid, st[3])
                if best is None:
                    unmatched += 1
                    continue
                errors.append(best[0])
                ids_of.setdefault(best[1], set()).add(f["properties"]["fused_id"])
                per = matched_to.setdefault(f["properties"]["fused_id"], {})
                per[best[1]] = per.get(best[1], 0) + 1
                same = f["properties"].get("class_id") == CLASS_IDS.get(best[2])
                classes["right" if same else "wrong"] += 1
        ing = stats.get("ingest", {})
        # Each fused id's identity (identities); "any": every fused id ever nearest to the object.
        identity = identities(matched_to)
        per_obj = [len(v) for v in identity.values()]
        any_obj = [len(v) for v in ids_of.values()]
        fig = {
            "drones": stats.get("drones"), "track_reports_used": ing.get("track_reports_used"),
            "digest_positions": ing.get("digest_positions"), "pictures": len(lines),
            "fused_ids": len(fused_ids), "tracked_samples_matched": len(errors),
            "unmatched": unmatched, "untimed": untimed,
            "error_median_m": round(pct(errors, 0.5), 2), "error_p95_m": round(pct(errors, 0.95), 2),
            "objects": len(identity), "objects_any": len(ids_of),
            "fused_ids_per_object": round(sum(per_obj) / len(per_obj), 3) if per_obj else float("nan"),
            "max_ids_per_object": max(per_obj) if per_obj else 0,
            "fused_ids_per_object_any": round(sum(any_obj) / len(any_obj), 3) if any_obj else float("nan"),
            "class": classes,
        }
        print("   %-6s %s" % (name, json.dumps(fig)))
        report["ground"][name] = fig


def main():
    global MGMOT, AUTOPILOT
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--system-id", type=int, default=1)
    args = ap.parse_args()
    out = args.out
    MGMOT, AUTOPILOT = (args.system_id, 191), (args.system_id, 1)
    dialect = load_dialect()
    radio = read_tlog(dialect, os.path.join(out, "gcs_radio.tlog"))
    router = read_tlog(dialect, os.path.join(out, "gcs_router.tlog"))
    report = {}
    print("\n==== SITL bench report (%s)" % out)

    print("\n-- 1. autopilot streams on the companion link (router tap), last 60 s")
    if router:
        end = router[-1][0]
        streams = {}
        for t, m in router:
            if sender(m)[0] == AUTOPILOT[0] and sender(m) != MGMOT and t >= end - 60:
                streams.setdefault("%s %d/%d" % ((m.get_type(),) + sender(m)), []).append(t)
        for k in sorted(streams):
            print("   %-45s %6d msgs %7.1f Hz" % (k, len(streams[k]), rate(streams[k])))
        report["streams_hz"] = {k: round(rate(v), 1) for k, v in streams.items()}
    acks = {}
    for _, m in router:
        if m.get_type() == "COMMAND_ACK" and m.command == dialect.MAV_CMD_SET_MESSAGE_INTERVAL:
            key = "to %d/%d: %s" % (m.target_system, m.target_component, dialect.enums["MAV_RESULT"][m.result].name)
            acks[key] = acks.get(key, 0) + 1
    print("   SET_MESSAGE_INTERVAL answers seen by the GCS: %s (the router delivers an answer only to its requester: mgmot's are in its stats below, `stream_requests`)" % acks)
    report["interval_acks"] = acks

    print("\n-- 2. TIMESYNC (router tap)")
    requests = {m.ts1: t for t, m in router if m.get_type() == "TIMESYNC" and m.tc1 == 0 and sender(m) == MGMOT}
    answers = [(t, m) for t, m in router if m.get_type() == "TIMESYNC" and m.tc1 != 0 and sender(m) == AUTOPILOT]
    matched = [(t, m) for t, m in answers if m.ts1 in requests]
    offsets = [(m.tc1 - m.ts1) / 1e9 for _, m in matched]
    rtts = [(t - requests[m.ts1]) * 1e3 for t, m in matched]
    others = [m for _, m in router if m.get_type() == "TIMESYNC" and m.tc1 != 0 and sender(m) not in (AUTOPILOT, MGMOT)]
    print("   (requests and answers are addressed: the router delivers them only between mgmot and the autopilot, so a GCS-side tap sees them only without a router)")
    print("   requests from mgmot %d, answered by the autopilot %d; offset autopilot - mgmot clock: median %.4f s (spread %.4f s); round trip at the tap median %.1f ms, p95 %.1f ms; answers from others %d"
          % (len(requests), len(matched), statistics.median(offsets) if offsets else float("nan"),
             (max(offsets) - min(offsets)) if offsets else float("nan"), pct(rtts, 0.5), pct(rtts, 0.95), len(others)))
    report["timesync"] = {"requests": len(requests), "answers": len(matched), "answers_from_others": len(others)}

    print("\n-- 3. camera pose used by the renderer (telemetry) vs SITL's own state (SIMSTATE)")
    # SIMSTATE has no time of its own: each takes the time_boot of the ATTITUDE before it.
    # Per autopilot boot (a reboot starts its clock again): SIMSTATE by boot and frames by boot.
    sim_boots = [[]]
    boot_ms = None
    for t, m in radio:
        if m.get_type() == "ATTITUDE":
            if boot_ms is not None and m.time_boot_ms + 1000 < boot_ms:
                sim_boots.append([])
            boot_ms = m.time_boot_ms
        elif m.get_type() == "SIMSTATE" and boot_ms is not None:
            sim_boots[-1].append((boot_ms * 1000, m))
    sim = [x for b in sim_boots for x in b]
    cam_path = os.path.join(out, "truth", "camera.csv")
    if sim and os.path.exists(cam_path):
        rows = list(csv.DictReader(open(cam_path)))
        dpos, datt = [], []
        import bisect
        sim_times = [[x[0] for x in b] for b in sim_boots]
        boot, last = 0, None
        for r in rows:
            stamp = int(r["frame_stamp_us"])
            if last is not None and stamp < last - 1_000_000:
                boot += 1
            last = stamp
            sim = sim_boots[boot] if boot < len(sim_boots) else []
            times = sim_times[boot] if boot < len(sim_boots) else []
            j = bisect.bisect_left(times, stamp)
            cands = [sim[k] for k in (j - 1, j) if 0 <= k < len(sim)]
            if not cands:
                continue
            us, s = min(cands, key=lambda c: abs(c[0] - stamp))
            if abs(us - stamp) > 100_000:
                continue
            lat, lon = s.lat * 1e-7, s.lng * 1e-7
            dn = (float(r["lat_deg"]) - lat) * 111320.0
            de = (float(r["lon_deg"]) - lon) * 111320.0 * math.cos(math.radians(lat))
            dpos.append(math.hypot(dn, de))
            for a, b in ((float(r["vehicle_roll_deg"]), math.degrees(s.roll)),
                         (float(r["vehicle_pitch_deg"]), math.degrees(s.pitch)),
                         (float(r["vehicle_yaw_deg"]), math.degrees(s.yaw))):
                datt.append(abs((a - b + 180) % 360 - 180))
        print("   %d frames compared: horizontal position median %.2f m, p95 %.2f m; vehicle roll/pitch/yaw median %.2f deg, p95 %.2f deg (SIMSTATE timed by the ATTITUDE before it: +-20 ms)"
              % (len(dpos), pct(dpos, 0.5), pct(dpos, 0.95), pct(datt, 0.5), pct(datt, 0.95)))
        report["pose_vs_sitl"] = {"frames": len(dpos), "pos_p95_m": pct(dpos, 0.95), "att_p95_deg": pct(datt, 0.95)}
    else:
        print("   no SIMSTATE or no truth/camera.csv")

    print("\n-- 4. geolocation error of mgmot's tracks (mgmot-sim follow's check against the truth)")
    tr = os.path.join(out, "track_report.json")
    if os.path.exists(tr):
        r = json.load(open(tr))
        print("   " + json.dumps({k: v for k, v in r.items() if not isinstance(v, (list, dict))}))
        report["tracks"] = {k: v for k, v in r.items() if not isinstance(v, (list, dict))}
    else:
        print("   no track report")

    print("\n-- 5. mgmot's messages at the ground stations")
    kinds = ["HEARTBEAT", "MGMOT_TRACK", "TARGET_ABSOLUTE", "CAMERA_TRACKING_IMAGE_STATUS",
             "CAMERA_TRACKING_GEO_STATUS", "STATUSTEXT", "COMMAND_ACK"]
    for name, log in (("router (direct path)", router), ("radio (autopilot's telemetry link)", radio)):
        counts = {k: 0 for k in kinds}
        texts = []
        for _, m in log:
            if sender(m) == MGMOT and m.get_type() in counts:
                counts[m.get_type()] += 1
                if m.get_type() == "STATUSTEXT" and len(texts) < 8:
                    texts.append(m.text)
        print("   %-36s %s" % (name, counts))
        for x in texts:
            print("      STATUSTEXT: %s" % x)
        # tracking_status is a bitmask: ACTIVE 1, ERROR 2 (active, but the target is lost: no
        # position).
        geo = [m for _, m in log if sender(m) == MGMOT and m.get_type() == "CAMERA_TRACKING_GEO_STATUS"
               and m.tracking_status & 1 and not m.tracking_status & 2]
        lost = sum(1 for _, m in log if sender(m) == MGMOT and m.get_type() == "CAMERA_TRACKING_GEO_STATUS"
                   and m.tracking_status & 2)
        if geo or lost:
            m = geo[len(geo) // 2] if geo else None
            print("      CAMERA_TRACKING_GEO_STATUS active with a position: %d%s; active, target lost (ERROR): %d"
                  % (len(geo), ", e.g. lat %.6f lon %.6f h_acc %.1f m dist %.0f m" % (m.lat * 1e-7, m.lon * 1e-7, m.h_acc, m.dist) if m else "", lost))
        report["at_" + name.split()[0]] = counts
    log = os.path.join(out, "mgmot.log")
    if os.path.exists(log):
        import re
        plain = re.sub(r"\x1b\[[0-9;]*m", "", open(log, errors="replace").read())
        for line in plain.splitlines():
            if "refused a stream" in line or "autopilot back" in line:
                print("   mgmot log: " + line[line.find(" ", 30) + 1:][:160])
    stats = os.path.join(out, "mgmot_stats.json")
    if os.path.exists(stats):
        s = json.load(open(stats))
        print("\n   mgmot: %s" % {k: v for k, v in s.items() if not isinstance(v, (list, dict))})
        print("   mgmot link: %s" % s.get("link"))
    reboot_section(out, dialect, router, report)
    ground_section(out, router, report)
    json.dump(report, open(os.path.join(out, "report.json"), "w"), indent=1, default=str)


if __name__ == "__main__":
    main()
