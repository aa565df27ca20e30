#!/usr/bin/env bash
# The integrator's bench rehearsal against a real autopilot: ArduCopter SITL built from source,
# our renderer following it (`mgmot-sim follow`), mgmot, and a ground station on both paths.
#
#   SITL SERIAL0 (tcp 5760) = the telemetry radio  <-- bench_sitl_fly.py (flies; radio tap)
#   SITL SERIAL2 (tcp 5763) = the companion UART   <-- mavlink-router --> udp 14550 GCS (router tap)
#                                                                     --> udp 14551 mgmot run
#                                                                     --> udp 14552 mgmot-sim follow
#   mgmot-sim follow --frames unix:frames.sock --> mgmot run
#
# Usage: scripts/bench_sitl.sh ARDUPILOT_DIR [--out DIR] [--router PATH_TO_mavlink-routerd]
#
# ARDUPILOT_DIR holds a built ArduCopter SITL (build/sitl/bin/arducopter; see the README's
# "Bench rehearsal with ArduPilot SITL"). The vehicle gets firmware-config/ardupilot/
# mgmot-servo-gimbal.parm on top of SITL's copter defaults. Prints, at the end: messages per
# type and rate at each tap, the TIMESYNC offsets, camera pose against SITL's own state,
# geolocation error of every reported track, and which of mgmot's messages reached each ground
# station. Not part of CI: the ArduPilot sources are not reachable there.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD

ap_dir=""
out=""
router="${MAVLINK_ROUTERD:-}"
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --router) router="$2"; shift 2 ;;
    -h|--help) sed -n '2,19p' "$0"; exit 0 ;;
    *) if [ -z "$ap_dir" ]; then ap_dir="$1"; shift; else echo "bench: unexpected argument $1" >&2; exit 2; fi ;;
  esac
done
if [ -z "$ap_dir" ] || [ ! -x "$ap_dir/build/sitl/bin/arducopter" ]; then
  echo "bench: usage: scripts/bench_sitl.sh ARDUPILOT_DIR; ARDUPILOT_DIR/build/sitl/bin/arducopter must exist" >&2
  echo "       (./waf configure --board sitl && ./waf copter in an ArduPilot checkout; see the README)" >&2
  exit 2
fi
ap_dir=$(cd "$ap_dir" && pwd)
if [ -z "$router" ]; then router=$(command -v mavlink-routerd || true); fi
if [ -z "$router" ] || [ ! -x "$router" ]; then
  echo "bench: mavlink-routerd not found: put it on PATH, set MAVLINK_ROUTERD or pass --router" >&2
  exit 2
fi
out=${out:-$(mktemp -d "${TMPDIR:-/tmp}/mgmot-sitl.XXXXXX")}
mkdir -p "$out"
echo "bench: output in $out"

bash scripts/setup.sh >/dev/null
if [ ! -x .venv/bin/python3 ] || ! .venv/bin/python3 -c "import pymavlink" 2>/dev/null; then
  python3 -m venv .venv && .venv/bin/python3 -m pip install -q -r scripts/requirements-test.txt
fi
cargo build --release -q -p mgmot -p mgmot-sim
ort=""
if ort=$(bash scripts/detect_fetch_onnxruntime.sh 2>/dev/null); then backend=onnxruntime; else backend=tract; fi

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT

home="47.6721,9.2679,395,0"
mkdir -p "$out/sitl"
(cd "$out/sitl" && exec "$ap_dir/build/sitl/bin/arducopter" --model + --speedup 1 -I0 --home "$home" \
  --defaults "$ap_dir/Tools/autotest/default_params/copter.parm,$repo/firmware-config/ardupilot/mgmot-servo-gimbal.parm" \
  > "$out/sitl.log" 2>&1) &
pids+=($!)

cat > "$out/router.conf" <<EOF
[General]
TcpServerPort = 0
ReportStats = false
[TcpEndpoint autopilot]
Address = 127.0.0.1
Port = 5763
[UdpEndpoint gcs]
Mode = Normal
Address = 127.0.0.1
Port = 14550
[UdpEndpoint mgmot]
Mode = Normal
Address = 127.0.0.1
Port = 14551
[UdpEndpoint follow]
Mode = Normal
Address = 127.0.0.1
Port = 14552
EOF

# mgmot's config: the bench's link, frames, detector and servo gimbal; defaults elsewhere.
cat > "$out/mgmot.toml" <<EOF
[mavlink]
connection = "udpin:127.0.0.1:14551"
system_id = 1
component_id = 191
autopilot_component_id = 1

[telemetry]
gimbal_report = "servo_body_frame"
water_level_amsl_m = 395.0

[frames]
source = "sim"
socket = "$out/frames.sock"

[camera]
hfov_deg = 70.0

[detector]
kind = "onnx"
model = "$repo/models/mgmot-det-fp32.onnx"
backend = "$backend"
EOF
if [ "$backend" = onnxruntime ]; then echo "ort_library = \"$ort\"" >> "$out/mgmot.toml"; fi
printf '\n[recording]\ndir = "%s/flights"\nkeyframe_every_s = 5.0\n' "$out" >> "$out/mgmot.toml"

.venv/bin/python3 scripts/bench_sitl_fly.py --sitl-port 5760 --router-port 14550 --out "$out" &
fly=$!
pids+=($fly)
sleep 3
"$router" -c "$out/router.conf" > "$out/router.log" 2>&1 &
pids+=($!)
target/release/mgmot-sim follow -s calm_baseline --mavlink udpin:127.0.0.1:14552 \
  --frames "unix:$out/frames.sock" --gimbal-report body --duration-s 600 \
  --truth-out "$out/truth" --track-report "$out/track_report.json" > "$out/follow.log" 2>&1 &
follow=$!
pids+=($follow)
# Flights an earlier run left in the same --out: the replay and review below take this run's.
earlier_flights=$(for f in "$out"/flights/*/; do if [ -d "$f" ]; then echo "$f"; fi; done)
target/release/mgmot run -v --config "$out/mgmot.toml" --stats-json "$out/mgmot_stats.json" > "$out/mgmot.log" 2>&1 &
mgmot=$!
pids+=($mgmot)

fly_rc=0
wait "$fly" || fly_rc=$?
if [ "$fly_rc" -ne 0 ]; then echo "bench: the flight script failed (exit $fly_rc); reporting what was recorded" >&2; fi
kill -INT "$mgmot" "$follow" 2>/dev/null || true
wait "$mgmot" "$follow" 2>/dev/null || true
.venv/bin/python3 scripts/bench_sitl_report.py "$out"
# The flight mgmot recorded (its tlog holds ArduPilot's own packets): replayed, and reviewed
# against the simulator's truth.
# Flight folders are named after their UTC start, so the newest one this run made sorts last.
flight=""
for f in "$out"/flights/*/; do
  [ -d "$f" ] || continue
  case $'\n'"$earlier_flights"$'\n' in *$'\n'"$f"$'\n'*) ;; *) flight=$f ;; esac
done
if [ -n "$flight" ]; then
  target/release/mgmot replay "$flight" --out "$out/replay" | sed 's/^/replay: /'
  target/release/mgmot review "$flight" --truth "$out/truth" --out "$out/report/report.html" | sed 's/^/review: /'
else
  echo "bench: mgmot recorded no flight in this run (see $out/mgmot.log)" >&2
fi
exit "$fly_rc"
