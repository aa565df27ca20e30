#!/usr/bin/env python3
"""A UDP MAVLink tap between an autopilot (or mgmot-sim) and `mgmot run`, decoding what mgmot
sends with pymavlink and the project's dialect (firmware-config/mavlink/mgmot.xml).

    autopilot --udpout--> [tap :LISTEN] --> mgmot (udpin :MGMOT)
    autopilot <---------- [tap]         <-- mgmot's replies (decoded here)

pymavlink's mavgen generates the dialect from the XML at start (the standard definitions it
includes ship with pymavlink). Every message from mgmot is decoded; MGMOT_TRACK, HEARTBEAT,
STATUSTEXT and TARGET_ABSOLUTE are written as JSON lines to --out. Decoding failures are counted
and make the exit status 1.

Usage: runtime_mavlink_tap.py --listen 14561 --mgmot 14562 --out msgs.jsonl --idle-s 5
"""
import argparse
import importlib.util
import json
import os
import shutil
import socket
import sys
import tempfile
import time

import pymavlink
from pymavlink.generator import mavgen

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DIALECT_XML = os.path.join(REPO, "firmware-config", "mavlink", "mgmot.xml")


def load_dialect():
    """Generates the Python module of mgmot.xml (MAVLink 2) and imports it."""
    std = os.path.join(os.path.dirname(pymavlink.__file__), "dialects", "v20")
    work = tempfile.mkdtemp(prefix="mgmot-dialect-")
    for name in os.listdir(std):
        if name.endswith(".xml"):
            shutil.copy(os.path.join(std, name), work)
    xml = os.path.join(work, "mgmot.xml")
    shutil.copy(DIALECT_XML, xml)
    out = os.path.join(work, "mgmot.py")
    opts = mavgen.Opts(out, wire_protocol="2.0", language="Python3", validate=True)
    if not mavgen.mavgen(opts, [xml]):
        sys.exit("mavgen failed on " + DIALECT_XML)
    spec = importlib.util.spec_from_file_location("mgmot_dialect", out)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--listen", type=int, required=True, help="UDP port the autopilot sends to")
    ap.add_argument("--mgmot", type=int, required=True, help="UDP port mgmot listens on (udpin)")
    ap.add_argument("--out", required=True, help="JSON lines of decoded mgmot messages")
    ap.add_argument("--idle-s", type=float, default=5.0, help="stop after this long without traffic")
    ap.add_argument("--max-s", type=float, default=600.0, help="stop after this long in any case")
    args = ap.parse_args()

    dialect = load_dialect()
    mav = dialect.MAVLink(None)
    mav.robust_parsing = True
    up = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    up.bind(("127.0.0.1", args.listen))
    down = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    down.bind(("127.0.0.1", 0))
    up.setblocking(False)
    down.setblocking(False)
    autopilot = None
    counts = {}
    bad = 0
    start = last = time.monotonic()
    with open(args.out, "w") as out:
        while time.monotonic() - last < args.idle_s and time.monotonic() - start < args.max_s:
            moved = False
            try:
                data, autopilot = up.recvfrom(65535)
                down.sendto(data, ("127.0.0.1", args.mgmot))
                moved = True
            except BlockingIOError:
                pass
            try:
                data, _ = down.recvfrom(65535)
                moved = True
                if autopilot is not None:
                    up.sendto(data, autopilot)
                try:
                    msgs = mav.parse_buffer(data) or []
                except Exception:  # a frame pymavlink rejects
                    bad += 1
                    msgs = []
                for m in msgs:
                    name = m.get_type()
                    if name == "BAD_DATA":
                        bad += 1
                        continue
                    counts[name] = counts.get(name, 0) + 1
                    if name in ("MGMOT_TRACK", "HEARTBEAT", "STATUSTEXT", "TARGET_ABSOLUTE"):
                        d = m.to_dict()
                        d["_srcSystem"], d["_srcComponent"] = m.get_srcSystem(), m.get_srcComponent()
                        out.write(json.dumps(d, default=str) + "\n")
            except BlockingIOError:
                pass
            if moved:
                last = time.monotonic()
            else:
                time.sleep(0.001)
    print(json.dumps({"counts": counts, "bad": bad}))
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
