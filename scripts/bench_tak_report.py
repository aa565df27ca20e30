#!/usr/bin/env python3
"""The report of scripts/bench_tak.sh: what mgmot sent (its --stats-json) against what the TAK
client received through the server, and the latency from an event's creation (its `time`) to
its arrival at the client. Every received event is also checked by cot_check.py.

Usage: bench_tak_report.py RECEIVED.jsonl MGMOT_STATS.json [--json OUT]
"""
import argparse
import json
import re
import sys
from datetime import datetime
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cot_check  # noqa: E402


def percentile(values, q):
    if not values:
        return float("nan")
    v = sorted(values)
    k = min(len(v) - 1, max(0, round(q / 100 * (len(v) - 1))))
    return v[k]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("received")
    ap.add_argument("stats")
    ap.add_argument("--json")
    a = ap.parse_args()
    rows = [json.loads(line) for line in Path(a.received).read_text().splitlines() if line.strip()]
    stats = json.loads(Path(a.stats).read_text())
    cot = stats.get("cot") or {}
    # Ours: the event's own uid is mgmot's (the server also sends events that only link to
    # ours, e.g. the t-x-d-d it makes when mgmot disconnects).
    ours = [r for r in rows if re.search(r'<event\b[^>]*\buid="mgmot\.', r["xml"])]
    latencies = []
    for r in ours:
        m = re.search(r' time="([^"]+)"', r["xml"])
        if m:
            t = datetime.fromisoformat(m.group(1).replace("Z", "+00:00")).timestamp()
            latencies.append(r["rx_unix_s"] - t)
    check = cot_check.check([r["xml"] for r in ours])
    sent = cot.get("sent", 0)
    report = {
        "mgmot_events_made": cot.get("events", 0),
        "mgmot_sent": sent,
        "mgmot_replaced_while_away": cot.get("replaced", 0),
        "mgmot_dropped": cot.get("dropped", 0),
        "mgmot_connects": cot.get("connects", 0),
        "received_by_client": len(ours),
        "lost": sent - len(ours),
        "latency_s": {"p50": percentile(latencies, 50), "p95": percentile(latencies, 95),
                      "max": max(latencies) if latencies else float("nan")},
        "uids": check["uids"],
        "types": check["types"],
        "schema_problems": check["problems"][:10],
        "frames_processed": stats.get("frames_processed"),
        "frames_dropped": stats.get("frames_dropped"),
        "track_messages": stats.get("track_messages"),
    }
    if a.json:
        Path(a.json).write_text(json.dumps(report, indent=1))
    l = report["latency_s"]
    print(f"TAK bench: mgmot sent {sent} events (made {report['mgmot_events_made']}, "
          f"dropped {report['mgmot_dropped']}); the client received {len(ours)} through the "
          f"server: lost {report['lost']}")
    print(f"  latency creation -> client: p50 {l['p50']*1000:.0f} ms, p95 {l['p95']*1000:.0f} ms, "
          f"max {l['max']*1000:.0f} ms; {report['uids']} uids, types {report['types']}")
    print(f"  schema: {len(check['problems'])} problems"
          + (f" (first: {check['problems'][0]})" if check["problems"] else ""))
    ok = report["lost"] == 0 and not check["problems"] and len(ours) > 0 and l["p95"] <= 1.0
    print("  verdict: " + ("PASS (0 lost, p95 <= 1 s, schema clean)" if ok else "FAIL"))
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
