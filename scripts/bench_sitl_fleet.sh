#!/usr/bin/env bash
# Two drones against two real autopilots: two ArduCopter SITL instances (system ids 1 and 2)
# fly the search leg of scripts/bench_sitl.sh side by side over the same water, each with its
# own renderer, mgmot, mavlink-router and ground stations (a whole bench_sitl.sh each, with
# --instance 0 and 1). Both routers also forward to one shared `mgmot ground`, the
# coordinator's picture, which must give each object both drones saw one fused id.
#
#   drone 1: SITL -I0 --sysid 1, 30 m, the leg at home's longitude    --> router 1 --+
#   drone 2: SITL -I1 --sysid 2, 40 m, the leg 10 m east of drone 1's --> router 2 --+--> udp 14600
#                                                                                      mgmot ground (fleet)
#
# Both renderers place the one scenario (calm_baseline) around the same home, so they render
# the same objects. At the end: each drone's bench report (OUT/d1, OUT/d2), then the fleet's
# fused picture against the truth (scripts/bench_sitl_fleet_report.py; OUT/fleet_report.json).
#
# Usage: scripts/bench_sitl_fleet.sh ARDUPILOT_DIR [--out DIR] [--router PATH_TO_mavlink-routerd]
#                                    [--bin-dir DIR] [--python PY]
# The options are bench_sitl.sh's. The two benches share this machine: on 2 cores a model run
# takes about twice as long, and `tile = "auto"` then keeps to whole frames. Not part of CI
# (no ArduPilot there).
set -euo pipefail
cd "$(dirname "$0")/.."

ap_dir=""
out=""
router="${MAVLINK_ROUTERD:-}"
bin_dir=""
python=""
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --router) router="$2"; shift 2 ;;
    --bin-dir) bin_dir="$2"; shift 2 ;;
    --python) python="$2"; shift 2 ;;
    -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
    *) if [ -z "$ap_dir" ]; then ap_dir="$1"; shift; else echo "fleet: unexpected argument $1" >&2; exit 2; fi ;;
  esac
done
if [ -z "$ap_dir" ]; then
  echo "fleet: usage: scripts/bench_sitl_fleet.sh ARDUPILOT_DIR [--out DIR] [--router PATH] [--bin-dir DIR]" >&2
  exit 2
fi
out=${out:-$(mktemp -d "${TMPDIR:-/tmp}/mgmot-fleet.XXXXXX")}
mkdir -p "$out/ground"
out=$(cd "$out" && pwd)
echo "fleet: output in $out"

# Built and set up once, before the two benches start side by side.
# shellcheck source=scripts/lib/bench_tools.sh
source scripts/lib/bench_tools.sh
bench_binaries
bench_python
common=(--bin-dir "$bin_dir" --python "$python" --ground-forward 14600)
if [ -n "$router" ]; then common+=(--router "$router"); fi

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT

"$bin_dir/mgmot" ground --connection udpin:127.0.0.1:14600 --http "" \
  --record "$out/ground/fleet.jsonl" --geojson "$out/ground/fleet.geojson" \
  --stats-json "$out/ground/fleet_stats.json" > "$out/ground/fleet.log" 2>&1 &
ground=$!
pids+=($ground)

bash scripts/bench_sitl.sh "$ap_dir" "${common[@]}" --instance 0 --out "$out/d1" > "$out/d1.log" 2>&1 &
d1=$!
pids+=($d1)
bash scripts/bench_sitl.sh "$ap_dir" "${common[@]}" --instance 1 --altitude-m 40 --east-m 10 --out "$out/d2" > "$out/d2.log" 2>&1 &
d2=$!
pids+=($d2)
rc=0
wait "$d1" || { echo "fleet: drone 1's bench failed (see $out/d1.log)" >&2; rc=1; }
wait "$d2" || { echo "fleet: drone 2's bench failed (see $out/d2.log)" >&2; rc=1; }
kill -INT "$ground" 2>/dev/null || true
wait "$ground" 2>/dev/null || true
for k in 1 2; do
  echo "== drone $k: the last lines of its bench (whole report in $out/d$k.log)"
  tail -n 30 "$out/d$k.log"
done
"$python" scripts/bench_sitl_fleet_report.py "$out"
exit "$rc"
