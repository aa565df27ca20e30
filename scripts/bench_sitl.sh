#!/usr/bin/env bash
# The integrator's bench rehearsal against a real autopilot: ArduCopter SITL built from source,
# our renderer following it (`mgmot-sim follow`), mgmot, and a ground station on both paths.
#
#   SITL SERIAL0 (tcp 5760) = the telemetry radio  <-- bench_sitl_fly.py (flies; radio tap)
#   SITL SERIAL1 (udp 14554) = a second radio      --> mgmot ground (radio: the digest only)
#   SITL SERIAL2 (tcp 5763) = the companion UART   <-- mavlink-router --> udp 14550 GCS (router tap)
#                                                                     --> udp 14551 mgmot run
#                                                                     --> udp 14552 mgmot-sim follow
#                                                                     --> udp 14553 mgmot ground (router)
#   mgmot-sim follow --frames unix:frames.sock --> mgmot run
#
# The two mgmot ground processes (the coordinator's side) record their fused pictures in
# OUT/ground/{router,radio}.jsonl; the report scores them against the truth (section 7).
#
# Usage: scripts/bench_sitl.sh ARDUPILOT_DIR [--out DIR] [--router PATH_TO_mavlink-routerd]
#                              [--bin-dir DIR] [--python PY]
#                              [--reboot-at S [--reboot-landed | --reboot-dry-run]]
#                              [--instance N] [--altitude-m M] [--east-m M] [--ground-forward PORT]
#
# --bin-dir DIR: use DIR/mgmot and DIR/mgmot-sim as they are (no setup.sh, no cargo build;
# default: build them with cargo into target/release). --python PY: the Python with pymavlink
# for the ground station and the report (default: .venv/bin/python3, created when missing).
# --reboot-at S: the ground station reboots the autopilot S seconds after it starts
# (MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN; in the air, forced, unless --reboot-landed: land and
# disarm first), waits for it to come back and flies the pattern again; mgmot, follow and the
# router keep running. The report then compares the tracks before and after the reboot.
# --reboot-dry-run: the same flight without the reboot (lands and disarms at S, flies again).
# --instance N: SITL instance N (-IN) with MAVLink system id N+1; every port above moves up by
# 10*N (SITL's own rule for its TCP ports), so several benches can fly at once, as
# scripts/bench_sitl_fleet.sh does. --altitude-m / --east-m: the search altitude (30 m) and
# the pattern's offset east of home (0 m). --ground-forward PORT: the router also forwards
# everything to udp PORT (a fleet's shared mgmot ground).
#
# ARDUPILOT_DIR holds a built ArduCopter SITL (build/sitl/bin/arducopter; see
# docs/sitl-bench.md). The vehicle gets firmware-config/ardupilot/
# mgmot-servo-gimbal.parm on top of SITL's copter defaults. Prints, at the end: messages per
# type and rate at each tap, the TIMESYNC offsets, camera pose against SITL's own state,
# geolocation error of every reported track, which of mgmot's messages reached each ground
# station, and mgmot ground's fused picture on each path against the truth. Not part of CI:
# the ArduPilot sources are not reachable there.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD

ap_dir=""
out=""
router="${MAVLINK_ROUTERD:-}"
bin_dir=""
python=""
fly_args=()
instance=0
ground_forward=""
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --router) router="$2"; shift 2 ;;
    --bin-dir) bin_dir="$2"; shift 2 ;;
    --python) python="$2"; shift 2 ;;
    --reboot-at) fly_args+=(--reboot-at "$2"); shift 2 ;;
    --reboot-landed) fly_args+=(--reboot-landed); shift ;;
    --reboot-dry-run) fly_args+=(--reboot-dry-run); shift ;;
    --instance) instance="$2"; shift 2 ;;
    --altitude-m) fly_args+=(--altitude-m "$2"); shift 2 ;;
    --east-m) fly_args+=(--east-m "$2"); shift 2 ;;
    --ground-forward) ground_forward="$2"; shift 2 ;;
    -h|--help) sed -n '2,40p' "$0"; exit 0 ;;
    *) if [ -z "$ap_dir" ]; then ap_dir="$1"; shift; else echo "bench: unexpected argument $1" >&2; exit 2; fi ;;
  esac
done
if [ -z "$ap_dir" ] || [ ! -x "$ap_dir/build/sitl/bin/arducopter" ]; then
  echo "bench: usage: scripts/bench_sitl.sh ARDUPILOT_DIR; ARDUPILOT_DIR/build/sitl/bin/arducopter must exist" >&2
  echo "       (./waf configure --board sitl && ./waf copter in an ArduPilot checkout; see docs/sitl-bench.md)" >&2
  exit 2
fi
ap_dir=$(cd "$ap_dir" && pwd)
case "$instance" in
  [0-9]) ;;
  *) echo "bench: --instance takes 0 to 9, not '$instance'" >&2; exit 2 ;;
esac
sysid=$((instance + 1))
p=$((10 * instance))
if [ -z "$router" ]; then router=$(command -v mavlink-routerd || true); fi
if [ -z "$router" ] || [ ! -x "$router" ]; then
  echo "bench: mavlink-routerd not found: put it on PATH, set MAVLINK_ROUTERD or pass --router" >&2
  exit 2
fi
out=${out:-$(mktemp -d "${TMPDIR:-/tmp}/mgmot-sitl.XXXXXX")}
mkdir -p "$out"
echo "bench: output in $out"

# shellcheck source=scripts/lib/bench_tools.sh
source scripts/lib/bench_tools.sh
bench_binaries
bench_python
ort=""
if ort=$(bash scripts/detect_fetch_onnxruntime.sh 2>/dev/null); then backend=onnxruntime; else backend=tract; fi

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT

home="47.6721,9.2679,395,0"
mkdir -p "$out/sitl"
# The shipped parameter file sets MAV_SYSID 1 (a single vehicle); a later defaults file wins
# over it, and over --sysid.
echo "MAV_SYSID $sysid" > "$out/sitl/sysid.parm"
(cd "$out/sitl" && exec "$ap_dir/build/sitl/bin/arducopter" --model + --speedup 1 -I"$instance" --home "$home" \
  --serial1 udpclient:127.0.0.1:$((14554 + p)) \
  --defaults "$ap_dir/Tools/autotest/default_params/copter.parm,$repo/firmware-config/ardupilot/mgmot-servo-gimbal.parm,$out/sitl/sysid.parm" \
  > "$out/sitl.log" 2>&1) &
pids+=($!)

cat > "$out/router.conf" <<EOF
[General]
TcpServerPort = 0
ReportStats = false
[TcpEndpoint autopilot]
Address = 127.0.0.1
Port = $((5763 + p))
[UdpEndpoint gcs]
Mode = Normal
Address = 127.0.0.1
Port = $((14550 + p))
[UdpEndpoint mgmot]
Mode = Normal
Address = 127.0.0.1
Port = $((14551 + p))
[UdpEndpoint follow]
Mode = Normal
Address = 127.0.0.1
Port = $((14552 + p))
[UdpEndpoint ground]
Mode = Normal
Address = 127.0.0.1
Port = $((14553 + p))
EOF
if [ -n "$ground_forward" ]; then
  printf '[UdpEndpoint fleet_ground]\nMode = Normal\nAddress = 127.0.0.1\nPort = %s\n' "$ground_forward" >> "$out/router.conf"
fi

# mgmot's config: the bench's link, frames, detector and servo gimbal; defaults elsewhere.
cat > "$out/mgmot.toml" <<EOF
[mavlink]
connection = "udpin:127.0.0.1:$((14551 + p))"
system_id = $sysid
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
if [ "$backend" = onnxruntime ]; then
  # As the example configuration: int8 on ONNX Runtime, tiles when they fit 15 frames/s, run
  # by the tile model (models/README.md, "The tile model").
  sed -i "s|^model = \"$repo/models/mgmot-det-fp32.onnx\"|model = \"$repo/models/mgmot-det-int8.onnx\"|" "$out/mgmot.toml"
  printf 'ort_library = "%s"\ntile = "auto"\ntile_model = "%s/models/mgmot-det-tiles-int8.onnx"\n' "$ort" "$repo" >> "$out/mgmot.toml"
fi
printf '\n[recording]\ndir = "%s/flights"\nkeyframe_every_s = 5.0\n' "$out" >> "$out/mgmot.toml"

# The ground side: one mgmot ground on the router (MGMOT_TRACK), one on SITL's second radio,
# where ArduPilot forwards mgmot's STATUSTEXT digest but drops MGMOT_TRACK.
mkdir -p "$out/ground"
grounds=()
for path in router:$((14553 + p)) radio:$((14554 + p)); do
  name=${path%%:*}
  "$bin_dir/mgmot" ground --connection "udpin:127.0.0.1:${path#*:}" --http "" \
    --record "$out/ground/$name.jsonl" --geojson "$out/ground/$name.geojson" \
    --stats-json "$out/ground/${name}_stats.json" > "$out/ground/$name.log" 2>&1 &
  grounds+=($!)
  pids+=($!)
done
"$python" scripts/bench_sitl_fly.py --sitl-port $((5760 + p)) --router-port $((14550 + p)) --system-id "$sysid" --out "$out" ${fly_args[@]+"${fly_args[@]}"} &
fly=$!
pids+=($fly)
sleep 3
"$router" -c "$out/router.conf" > "$out/router.log" 2>&1 &
pids+=($!)
"$bin_dir/mgmot-sim" follow -s calm_baseline --mavlink udpin:127.0.0.1:$((14552 + p)) \
  --frames "unix:$out/frames.sock" --gimbal-report body --duration-s 600 \
  --truth-out "$out/truth" --track-report "$out/track_report.json" > "$out/follow.log" 2>&1 &
follow=$!
pids+=($follow)
# Flights an earlier run left in the same --out: the replay and review below take this run's.
earlier_flights=$(for f in "$out"/flights/*/; do if [ -d "$f" ]; then echo "$f"; fi; done)
"$bin_dir/mgmot" run -v --config "$out/mgmot.toml" --stats-json "$out/mgmot_stats.json" > "$out/mgmot.log" 2>&1 &
mgmot=$!
pids+=($mgmot)

fly_rc=0
wait "$fly" || fly_rc=$?
if [ "$fly_rc" -ne 0 ]; then echo "bench: the flight script failed (exit $fly_rc); reporting what was recorded" >&2; fi
kill -INT "$mgmot" "$follow" "${grounds[@]}" 2>/dev/null || true
wait "$mgmot" "$follow" "${grounds[@]}" 2>/dev/null || true
"$python" scripts/bench_sitl_report.py "$out" --system-id "$sysid"
# The flight mgmot recorded (its tlog holds ArduPilot's own packets): replayed, and reviewed
# against the simulator's truth.
# Flight folders are named after their UTC start, so the newest one this run made sorts last.
flight=""
for f in "$out"/flights/*/; do
  [ -d "$f" ] || continue
  case $'\n'"$earlier_flights"$'\n' in *$'\n'"$f"$'\n'*) ;; *) flight=$f ;; esac
done
if [ -n "$flight" ]; then
  "$bin_dir/mgmot" replay "$flight" --out "$out/replay" | sed 's/^/replay: /'
  "$bin_dir/mgmot" review "$flight" --truth "$out/truth" --out "$out/report/report.html" | sed 's/^/review: /'
else
  echo "bench: mgmot recorded no flight in this run (see $out/mgmot.log)" >&2
fi
exit "$fly_rc"
