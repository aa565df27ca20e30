#!/usr/bin/env python3
"""Decodes a file of MAVLink 2 frames with pymavlink and the project's dialect
(firmware-config/mavlink/mgmot.xml, generated with mavgen at start) and prints one JSON object
per message on stdout. Exit status 1 if any frame fails to decode (bad CRC, unknown id, ...).

Usage: runtime_pymavlink_decode.py FRAMES.bin
"""
import contextlib
import io
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from runtime_mavlink_tap import load_dialect  # noqa: E402


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    with contextlib.redirect_stdout(io.StringIO()):  # mavgen's progress chatter
        dialect = load_dialect()
    mav = dialect.MAVLink(None)
    data = open(sys.argv[1], "rb").read()
    bad = 0
    for m in mav.parse_buffer(data) or []:
        if m.get_type() == "BAD_DATA":
            bad += 1
            continue
        d = m.to_dict()
        d["_srcSystem"], d["_srcComponent"] = m.get_srcSystem(), m.get_srcComponent()
        print(json.dumps(d, default=str))
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
