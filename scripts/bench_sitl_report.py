#!/usr/bin/env python3
"""The SITL bench's report (scripts/bench_sitl.sh): reads the two ground stations' tlogs, the
renderer's truth and track report and mgmot's stats from the bench's output folder and prints:

1. the autopilot's streams on the companion link (router tap) per type and rate, and the
   answers to the SET_MESSAGE_INTERVAL requests;
2. TIMESYNC: mgmot's requests, the autopilot's answers, offset and round trip;
3. the camera pose the renderer used (the telemetry) against SITL's own state (SIMSTATE);
4. the geolocation error of every MGMOT_TRACK against the truth (mgmot-sim follow's check);
5. which of mgmot's messages reached each ground station: through the router (a direct path)
   and through the autopilot's telemetry radio alone.

Usage: bench_sitl_report.py OUT_DIR
"""
import csv
import json
import math
import os
import statistics
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from runtime_mavlink_tap import load_dialect  # noqa: E402

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


def main():
    out = sys.argv[1]
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
            if sender(m)[0] == 1 and sender(m) != MGMOT and t >= end - 60:
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
    sim = []
    boot_ms = None
    for t, m in radio:
        if m.get_type() == "ATTITUDE":
            boot_ms = m.time_boot_ms
        elif m.get_type() == "SIMSTATE" and boot_ms is not None:
            sim.append((boot_ms * 1000, m))
    cam_path = os.path.join(out, "truth", "camera.csv")
    if sim and os.path.exists(cam_path):
        rows = list(csv.DictReader(open(cam_path)))
        times = [s[0] for s in sim]
        dpos, datt = [], []
        import bisect
        for r in rows:
            stamp = int(r["frame_stamp_us"])
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
        geo = [m for _, m in log if sender(m) == MGMOT and m.get_type() == "CAMERA_TRACKING_GEO_STATUS" and m.tracking_status != 0]
        if geo:
            m = geo[len(geo) // 2]
            print("      CAMERA_TRACKING_GEO_STATUS active: %d, e.g. lat %.6f lon %.6f h_acc %.1f m dist %.0f m"
                  % (len(geo), m.lat * 1e-7, m.lon * 1e-7, m.h_acc, m.dist))
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
    json.dump(report, open(os.path.join(out, "report.json"), "w"), indent=1, default=str)


if __name__ == "__main__":
    main()
