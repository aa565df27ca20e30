#!/usr/bin/env python3
"""Checks Cursor-on-Target events: each against the CoT base event schema (scripts/cot/event.xsd,
with lxml), then what the schema cannot say: times in UTC with a `Z`, start <= stale and
time <= stale (an event that is stale at once is an end), a uid that keeps its type.

Usage: cot_check.py EVENTS_FILE [--json OUT]
EVENTS_FILE holds events back to back (a TCP stream's bytes, or UDP datagrams one after the
other). Prints a summary; exits 1 naming the first problems when any event fails.
"""
import argparse
import json
import re
import sys
from datetime import datetime
from pathlib import Path

from lxml import etree

XSD = Path(__file__).resolve().parent / "cot" / "event.xsd"
UTC = re.compile(r"^\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d+)?Z$")


def split_events(data: str):
    """The events of a stream: each from `<?xml` or `<event` to its `</event>`."""
    out = []
    pos = 0
    while True:
        end = data.find("</event>", pos)
        if end < 0:
            rest = data[pos:].strip()
            if rest:
                out.append(rest)  # a cut-off event: reported by the schema check
            return out
        out.append(data[pos:end + len("</event>")].strip())
        pos = end + len("</event>")


def parse_time(s: str) -> datetime:
    return datetime.fromisoformat(s.replace("Z", "+00:00"))


def check(events):
    schema = etree.XMLSchema(etree.parse(str(XSD)))
    problems = []
    types_of_uid = {}
    summary = {"events": 0, "uids": 0, "types": {}, "ended": 0, "deletes": 0}
    for i, text in enumerate(events):
        summary["events"] += 1
        try:
            root = etree.fromstring(text.encode())
        except etree.XMLSyntaxError as e:
            problems.append(f"event {i}: not XML: {e}")
            continue
        if not schema.validate(root):
            problems.append(f"event {i}: schema: {schema.error_log.last_error}")
            continue
        a = root.attrib
        for k in ("time", "start", "stale"):
            if not UTC.match(a[k]):
                problems.append(f"event {i}: {k}={a[k]!r} is not UTC with Z")
        try:
            time, start, stale = (parse_time(a[k]) for k in ("time", "start", "stale"))
        except ValueError as e:
            problems.append(f"event {i}: {e}")
            continue
        if start > stale or time > stale:
            problems.append(f"event {i}: stale {a['stale']} before time/start")
        t = a["type"]
        summary["types"][t] = summary["types"].get(t, 0) + 1
        if t == "t-x-d-d":
            summary["deletes"] += 1
            continue
        if time == stale:
            summary["ended"] += 1
        previous = types_of_uid.setdefault(a["uid"], t)
        if previous != t:
            problems.append(f"event {i}: uid {a['uid']} changed type {previous} -> {t}")
    summary["uids"] = len(types_of_uid)
    summary["problems"] = problems
    return summary


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("events")
    ap.add_argument("--json", help="write the summary here")
    args = ap.parse_args()
    data = Path(args.events).read_text(encoding="utf-8")
    summary = check(split_events(data))
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=1))
    print(f"cot_check: {summary['events']} events, {summary['uids']} uids, "
          f"{summary['ended']} ended, {summary['deletes']} deletes, types {summary['types']}")
    if summary["problems"]:
        for p in summary["problems"][:20]:
            print("  " + p, file=sys.stderr)
        print(f"cot_check: {len(summary['problems'])} problems", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
