#!/usr/bin/env python3
"""Decode mgmot-sim telemetry with pymavlink, an implementation independent of the Rust
mavlink crate, and print what was decoded as one JSON object on stdout.

Usage: sim_pymavlink_decode.py --port PORT [--seconds S]

Listens on udpin:127.0.0.1:PORT (MAVLink 2, common dialect). After the first message it
sends a TIMESYNC request and a MAV_CMD_REQUEST_MESSAGE for HOME_POSITION and records the
answers. Output keys: counts (per message type), rates_hz (from the autopilot's time_boot_ms
where the message has it, else arrival times), mavlink2 (all frames were v2), timesync_reply,
acks, samples (one decoded example per type).
"""
import argparse
import json
import os
import sys
import time

os.environ["MAVLINK20"] = "1"
try:
    from pymavlink import mavutil
except ImportError:
    print("pymavlink not installed", file=sys.stderr)
    sys.exit(3)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--seconds", type=float, default=4.0)
    args = ap.parse_args()

    conn = mavutil.mavlink_connection(
        f"udpin:127.0.0.1:{args.port}", dialect="common", source_system=255, source_component=190
    )
    print("ready", file=sys.stderr, flush=True)
    counts, stamps, samples = {}, {}, {}
    all_v2 = True
    timesync_reply = None
    acks = []
    asked = False
    ts1 = 123456789
    start = None
    while True:
        if start is not None and time.time() - start > args.seconds:
            break
        msg = conn.recv_match(blocking=True, timeout=0.2)
        if msg is None:
            if start is None and time.time() - t0() > 30:
                break
            continue
        if start is None:
            start = time.time()
        kind = msg.get_type()
        if kind == "BAD_DATA":
            counts["BAD_DATA"] = counts.get("BAD_DATA", 0) + 1
            continue
        all_v2 = all_v2 and bytes(msg.get_msgbuf())[:1] == b"\xfd"
        counts[kind] = counts.get(kind, 0) + 1
        t = getattr(msg, "time_boot_ms", None)
        stamps.setdefault(kind, []).append(t / 1000.0 if t is not None else time.time())
        if kind not in samples:
            samples[kind] = msg.to_dict()
        if kind == "TIMESYNC" and msg.ts1 == ts1:
            timesync_reply = {"tc1": msg.tc1, "ts1": msg.ts1}
        if kind == "COMMAND_ACK":
            acks.append({"command": msg.command, "result": msg.result})
        if not asked:
            asked = True
            conn.mav.timesync_send(0, ts1)
            conn.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 242, 0, 0, 0, 0, 0, 0)
    rates = {}
    for kind, ts in stamps.items():
        if len(ts) >= 3 and ts[-1] > ts[0]:
            rates[kind] = (len(ts) - 1) / (ts[-1] - ts[0])
    for s in samples.values():
        for k, v in list(s.items()):
            if isinstance(v, float) and v != v:
                s[k] = None
    print(json.dumps({
        "counts": counts,
        "rates_hz": rates,
        "mavlink2": all_v2,
        "timesync_reply": timesync_reply,
        "acks": acks,
        "samples": samples,
    }))


_T0 = time.time()


def t0():
    return _T0


if __name__ == "__main__":
    main()
