#!/usr/bin/env python3
"""A TAK client for scripts/bench_tak.sh: connects to a TAK server with pytak, introduces itself
with a self-report made by pytak, as ATAK sends one (the server takes a connection's first
event as the client's identity), then records every event the server forwards, with the UTC time it arrived, until
it is stopped (SIGTERM / SIGINT) or --seconds pass.

Output: one JSON object per line: {"rx_unix_s": ..., "xml": "<event .../>"}.
"""
import argparse
import asyncio
import json
import signal
import time
from configparser import ConfigParser

import pytak


async def run(url: str, out_path: str, seconds: float, ready_path: str):
    config = ConfigParser()
    config["c"] = {"COT_URL": url, "PYTAK_TLS_DONT_VERIFY": "1",
                   "PYTAK_TLS_DONT_CHECK_HOSTNAME": "1"}
    reader, writer = await pytak.protocol_factory(config["c"])
    writer.write(pytak.gen_cot(lat=0.0, lon=0.0, uid="mgmot-bench-client",
                               cot_type="a-f-G-U-C", stale=3600, callsign="bench-client"))
    await writer.drain()
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stop.set)
    if ready_path:
        open(ready_path, "w").write("ready\n")
    deadline = time.monotonic() + seconds
    n = 0
    with open(out_path, "w") as out:
        buf = b""
        while not stop.is_set() and time.monotonic() < deadline:
            try:
                chunk = await asyncio.wait_for(reader.read(65536), timeout=0.5)
            except asyncio.TimeoutError:
                continue
            if not chunk:
                break
            now = time.time()
            buf += chunk
            while b"</event>" in buf:
                end = buf.index(b"</event>") + len(b"</event>")
                event, buf = buf[:end], buf[end:]
                start = event.find(b"<event")
                out.write(json.dumps({"rx_unix_s": now,
                                      "xml": event[start:].decode("utf-8", "replace")}) + "\n")
                n += 1
            out.flush()
    writer.close()
    print(f"bench_tak_client: {n} events received from {url}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--url", default="tcp://127.0.0.1:8087")
    ap.add_argument("--out", required=True)
    ap.add_argument("--seconds", type=float, default=3600)
    ap.add_argument("--ready", default="", help="a file written once connected")
    a = ap.parse_args()
    asyncio.run(run(a.url, a.out, a.seconds, a.ready))


if __name__ == "__main__":
    main()
