#!/usr/bin/env bash
# The demo: the simulator generates a maritime scene (drone metadata, ground truth and a
# simulated detector's boxes), mgmot tracks it three ways (BoT-SORT baseline without
# metadata, MG-MOT online as in the air, MG-MOT offline), geolocates every track, and scores
# each run against the ground truth with the TrackEval-exact metrics.
#
#   ./scripts/demo.sh [SCENARIO ...]      (default: leave_and_return swimmer_group)
#
# Outputs land in out/demo/<scenario>/. Takes a few minutes on a fresh machine (release build).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh

echo "== building (release)"
cargo build --release --quiet -p mgmot -p mgmot-sim
bin=target/release
scenarios=("$@")
[ ${#scenarios[@]} -gt 0 ] || scenarios=(leave_and_return swimmer_group)

for sc in "${scenarios[@]}"; do
  dir=out/demo/$sc
  rm -rf "$dir"
  mkdir -p "$dir"
  echo
  echo "== scenario $sc: simulating telemetry, ground truth and detections"
  $bin/mgmot-sim detections --scenario "$sc" --out "$dir/detections.json" --gt-dir "$dir/gt"
  gt="$dir/gt/gt/gt.txt"
  ann="$dir/gt/annotations.json"
  for run in baseline online offline; do
    case $run in
      baseline) flags=(--no-metadata) ;;
      online) flags=(--mode online) ;;
      offline) flags=(--mode offline) ;;
    esac
    $bin/mgmot track --annotations "$ann" --detections "$dir/detections.json" "${flags[@]}" --out "$dir/$run" >/dev/null
    res=$(ls "$dir/$run"/*.txt)
    $bin/mgmot eval --gt "$gt" --pred "$res" --json > "$dir/$run/metrics.json"
  done
  python3 - "$dir" <<'PY'
import json, sys, os
d = sys.argv[1]
print(f"{'run':<10}{'HOTA':>8}{'AssA':>8}{'MOTA':>8}{'IDF1':>8}{'IDSW':>6}{'FP':>7}{'FN':>7}")
for run in ["baseline", "online", "offline"]:
    m = json.load(open(os.path.join(d, run, "metrics.json")))
    m = m.get("combined", m)
    print(f"{run:<10}{m['HOTA']:>8.3f}{m['AssA']:>8.3f}{m['MOTA']:>8.3f}{m['IDF1']:>8.3f}{m['IDSW']:>6}{m['FP']:>7}{m['FN']:>7}")
PY
  echo "geolocated tracks: $(ls "$dir"/offline/*_tracks.csv)"
done
echo
echo "baseline = BoT-SORT without metadata (a missed track still reported 2 frames, as online);"
echo "online = MG-MOT as flown (a re-identified track is"
echo "re-labelled w frames after it reappears, which the metrics count as an ID switch);"
echo "offline = MG-MOT with the paper's interpolation -> ReID -> interpolation post-processing."

# The live part: the simulator as autopilot (MAVLink over UDP) and camera (frames over a Unix
# socket) in real time, against `mgmot run` with the shipped detector. The simulator checks every
# MGMOT_TRACK that mgmot sends back against its ground truth and reports the geolocation error
# and which track ids each true object was reported under.
live_scenario="${MGMOT_DEMO_LIVE_SCENARIO:-calm_baseline}"
live_s="${MGMOT_DEMO_LIVE_S:-30}"
dir=out/demo/live
rm -rf "$dir"
mkdir -p "$dir"
backend=tract
model=models/mgmot-det-fp32.onnx   # tract's faster model (see models/README.md)
if ORT_DYLIB_PATH="${ORT_DYLIB_PATH:-$(bash scripts/detect_fetch_onnxruntime.sh 2>/dev/null)}" && [ -f "$ORT_DYLIB_PATH" ]; then
  export ORT_DYLIB_PATH
  backend=onnxruntime
  model=models/mgmot-det-int8.onnx
fi
port=$(python3 -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
cat > "$dir/mgmot.toml" <<TOML
[mavlink]
connection = "udpin:127.0.0.1:$port"
[frames]
source = "sim"
socket = "$PWD/$dir/frames.sock"
[detector]
kind = "onnx"
model = "$PWD/$model"
backend = "$backend"
# Tiles when they fit 15 frames/s (ONNX Runtime int8 here; not tract), run by the tile model
# (systemd/mgmot.example.toml; models/README.md, "The tile model").
tile = "auto"
tile_model = "$PWD/models/mgmot-det-tiles-int8.onnx"
[tracker.baseline]
# The shipped model's settings (systemd/mgmot.example.toml, models/README.md).
track_high_thresh = 0.4
world_low_confidence_to_lost = false
[recording]
dir = "$PWD/$dir/flights"
keyframe_every_s = 5.0
TOML
echo
echo "== live: mgmot-sim ($live_scenario, ${live_s} s real time, 1280x720 @ 30 fps) against mgmot run ($backend, $(basename "$model"))"
$bin/mgmot check-config "$dir/mgmot.toml" >/dev/null
# The detector's INFO lines (which backend and model, whether it tiles) go to mgmot.log too.
RUST_LOG="${RUST_LOG:-warn,mgmot::detect=info}" \
  $bin/mgmot run --config "$dir/mgmot.toml" --stats-json "$dir/stats.json" > "$dir/mgmot.log" 2>&1 &
mgmot_pid=$!
trap 'kill $mgmot_pid 2>/dev/null || true' EXIT
$bin/mgmot-sim run --scenario "$live_scenario" --duration-s "$live_s" --realtime \
  --mavlink "udpout:127.0.0.1:$port" --frames "unix:$PWD/$dir/frames.sock" \
  --truth-out "$dir/truth" --track-report "$dir/track_report.json" 2>&1 | tee "$dir/sim.log" | grep --line-buffered "mgmot tracks" || true
# mgmot stops by itself when the simulator closes the frame stream.
for _ in $(seq 1 50); do kill -0 $mgmot_pid 2>/dev/null || break; sleep 0.2; done
kill $mgmot_pid 2>/dev/null || true
wait $mgmot_pid 2>/dev/null || true
trap - EXIT
python3 - "$dir" <<'PY'
import json, os, sys
d = sys.argv[1]
r = json.load(open(os.path.join(d, "track_report.json")))
f = lambda v: "-" if v is None else f"{v:.2f} m"
print(f"MGMOT_TRACK messages received by the simulator: {r['messages']} "
      f"({r['matched']} at a true object, {r['wrong_class']} of them with another class, "
      f"{r['false_tracks']} false, {r['without_geolocation']} without geolocation)")
print(f"geolocation error vs ground truth: median {f(r['error_median_m'])}, p95 {f(r['error_p95_m'])}, max {f(r['error_max_m'])}")
for o in r["objects"]:
    said = ", ".join(f"{n} {k}" for n, k in sorted(o["classes_reported"].items(), key=lambda x: -x[1]))
    print(f"  true object {o['object_id']:>3} ({o['class']}): reported as track id(s) {o['track_ids']}, "
          f"after re-identification {o['final_track_ids']}; class in its messages: {said}; "
          f"worst error {o['error_max_m']:.1f} m, {f(o['error_max_tracked_m'])} while detected")
try:
    s = json.load(open(os.path.join(d, "stats.json")))
    print("mgmot:", {k: s[k] for k in ("frames_captured", "frames_processed", "frames_dropped", "track_messages") if k in s})
    for line in open(os.path.join(d, "mgmot.log"), errors="replace"):
        if "detector: tiling" in line or "detector: not tiling" in line or "tile model not loaded" in line:
            print("mgmot:", line.split("detector: ", 1)[1].strip())
except (OSError, ValueError, KeyError):
    print("mgmot: no stats written (see out/demo/live/mgmot.log)")
PY
# The flight mgmot recorded: replayed (online must reproduce it exactly) and reviewed against
# the simulator's truth.
flight=$(ls -d "$dir"/flights/*/ 2>/dev/null | head -n 1)
if [ -z "$flight" ]; then
  echo "mgmot recorded no flight (see $dir/mgmot.log)" >&2
  exit 1
fi
echo
echo "== the recorded flight: $flight"
$bin/mgmot replay "$flight" --out "$dir/replay" | sed 's/^/replay: /'
$bin/mgmot replay "$flight" --mode offline --out "$dir/replay-offline" >/dev/null
$bin/mgmot review "$flight" --truth "$dir/truth" --out "$dir/report/report.html" | sed 's/^/review: /'
echo "after-action report: $dir/report/report.html (open it in a browser; tracks.geojson and tracks.kml beside it)"
echo "logs and reports: $dir/"
