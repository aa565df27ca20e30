#!/usr/bin/env python3
"""Checks the live map page of `mgmot ground` in Debian's headless Chromium.

Usage: ground_map_check.py --url http://127.0.0.1:PORT/ --min-tracks N [--min-drones M]
                           [--min-footprints F] [--chromium PATH] [--wait-ms 6000]
                           [--save-dom FILE]

Chromium loads the page with a fresh profile and a virtual time budget (the page's 1 s polls
run in virtual time: 6000 ms gives about six of them, in a second or two of real time), then
dumps the DOM. The checks: <body data-updates> >= 1 (the page drew tracks.geojson at least
once), at least N <g class="track">, M <g class="drone"> and F <polygon class="footprint">,
and no console error.

Console messages: Chromium 156 logs them on stderr (with --enable-logging=stderr) as
    [PID:TID:MMDD/HHMMSS.UUUUUU:INFO:CONSOLE:LINE] "MESSAGE", source: URL (LINE)
always at INFO for a web page, whatever the level (console.log, .warn and .error read the
same), and uncaught exceptions as "Uncaught ..." messages. So every console message counts as
an error except the page's own warnings, which start with "mgmot map:" (the page warns once
per outage when tracks.geojson cannot be fetched; it never logs anything else). A line logged
at ERROR (Chromium does that for its built-in pages) is an error too.

Prints one JSON line: {"ok", "updates", "tracks", "drones", "console_errors",
"console_warnings"}. Exits 0 when every check passes, 1 when one fails (or Chromium fails), 2
when Chromium is not installed.
"""
import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
from html.parser import HTMLParser

TIMEOUT_S = 60
PAGE_WARNING_PREFIX = "mgmot map:"
# [21465:21465:1206/184045.769685:INFO:CONSOLE:5] "hello error", source: http://... (5)
# (older Chromiums wrote CONSOLE(5) instead of CONSOLE:5).
CONSOLE_LINE = re.compile(
    r'^\[[^\]]*?:(?P<level>[A-Z]+[0-9]*):CONSOLE(?::\d+|\(\d+\))\] "(?P<message>.*)", source: '
    r'(?P<source>.*) \((?P<line>\d+)\)\s*$'
)


class Dom(HTMLParser):
    """The body's data attributes, and the <g> elements of the map by class."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.body = {}
        self.tracks = 0
        self.drones = 0
        self.footprints = 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        classes = (a.get("class") or "").split()
        if tag == "body":
            self.body = a
        elif tag == "g" and "track" in classes:
            self.tracks += 1
        elif tag == "g" and "drone" in classes:
            self.drones += 1
        elif tag == "polygon" and "footprint" in classes:
            self.footprints += 1

    handle_startendtag = handle_starttag


def console_messages(stderr: str):
    """(errors, warnings): the console lines of Chromium's stderr, as they were logged."""
    errors, warnings = [], []
    for line in stderr.splitlines():
        if "CONSOLE" not in line and "console" not in line:
            continue
        m = CONSOLE_LINE.match(line)
        if not m:
            # A console line in a format this script does not know: better reported than lost.
            if ":CONSOLE" in line:
                errors.append(line.strip())
            continue
        message = m.group("message")
        if m.group("level") in ("ERROR", "FATAL") or message.startswith("Uncaught"):
            errors.append(line.strip())
        elif message.startswith(PAGE_WARNING_PREFIX):
            warnings.append(line.strip())
        else:
            errors.append(line.strip())  # level unknown (always INFO): not a message the page writes
    return errors, warnings


def find_chromium(name: str):
    if os.sep in name:
        return name if os.path.isfile(name) and os.access(name, os.X_OK) else None
    return shutil.which(name)


def run_chromium(chromium: str, url: str, wait_ms: int):
    """(returncode, stdout, stderr) of a headless Chromium dumping the DOM; returncode None on
    a timeout (the whole process group is killed then)."""
    with tempfile.TemporaryDirectory(prefix="ground-map-check-") as profile:
        cmd = [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--enable-logging=stderr",
            "--v=0",
            f"--virtual-time-budget={wait_ms}",
            f"--user-data-dir={profile}",
            "--dump-dom",
            url,
        ]
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                stdin=subprocess.DEVNULL, start_new_session=True)
        try:
            out, err = proc.communicate(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            # Chromium's renderer, GPU and zygote processes share its session: end them all.
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            out, err = proc.communicate()
            return None, out.decode("utf-8", "replace"), err.decode("utf-8", "replace")
        return proc.returncode, out.decode("utf-8", "replace"), err.decode("utf-8", "replace")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", required=True, help="the page, e.g. http://127.0.0.1:8080/")
    ap.add_argument("--min-tracks", type=int, required=True, help="at least this many g.track")
    ap.add_argument("--min-drones", type=int, default=0, help="at least this many g.drone")
    ap.add_argument("--min-footprints", type=int, default=0,
                    help="at least this many polygon.footprint (camera footprints)")
    ap.add_argument("--chromium", default="chromium", help="the Chromium binary (default: chromium on PATH)")
    ap.add_argument("--wait-ms", type=int, default=6000, help="virtual time the page runs before the dump")
    ap.add_argument("--save-dom", help="also write the dumped DOM to this file")
    args = ap.parse_args()

    chromium = find_chromium(args.chromium)
    if chromium is None:
        print(f"ground_map_check: Chromium not found ({args.chromium!r}): install Debian's "
              "package with apt (`apt-get install chromium`; scripts/setup.sh installs it)",
              file=sys.stderr)
        return 2

    rc, dom, stderr = run_chromium(chromium, args.url, args.wait_ms)
    problems = []
    if rc is None:
        problems.append(f"chromium timed out after {TIMEOUT_S} s (killed)")
    elif rc != 0:
        problems.append(f"chromium exited with {rc}")
    if args.save_dom:
        with open(args.save_dom, "w", encoding="utf-8") as f:
            f.write(dom)

    parsed = Dom()
    try:
        parsed.feed(dom)
        parsed.close()
    except Exception as e:  # html.parser is lenient; this is only for the unexpected
        problems.append(f"cannot parse the DOM: {e}")

    def int_attr(name):
        try:
            return int(parsed.body.get(name) or 0)
        except ValueError:
            return 0

    updates = int_attr("data-updates")
    errors, warnings = console_messages(stderr)
    if updates < 1:
        problems.append("the page never drew tracks.geojson (body data-updates is 0)")
    if parsed.tracks < args.min_tracks:
        problems.append(f"{parsed.tracks} g.track, fewer than {args.min_tracks}")
    if parsed.drones < args.min_drones:
        problems.append(f"{parsed.drones} g.drone, fewer than {args.min_drones}")
    if parsed.footprints < args.min_footprints:
        problems.append(f"{parsed.footprints} polygon.footprint, fewer than {args.min_footprints}")
    if errors:
        problems.append(f"{len(errors)} console error(s)")
    if rc != 0 and not dom.strip():
        # Nothing to judge: show what Chromium said, less its usual D-Bus noise.
        tail = [l for l in stderr.splitlines() if "dbus" not in l][-10:]
        problems.extend(tail)

    summary = {
        "ok": not problems,
        "updates": updates,
        "tracks": parsed.tracks,
        "body_tracks": int_attr("data-tracks"),
        "drones": parsed.drones,
        "footprints": parsed.footprints,
        "console_errors": errors,
        "console_warnings": warnings,
        "problems": problems,
    }
    print(json.dumps(summary))
    return 0 if not problems else 1


if __name__ == "__main__":
    sys.exit(main())
