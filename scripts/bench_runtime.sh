#!/usr/bin/env bash
# End-to-end runtime benchmark: mgmot-sim in real time (1280x720 @ 30 fps, a busy scenario) as
# autopilot (MAVLink over UDP) and camera (Unix socket), and a release `mgmot run` with the
# real ONNX detector. Prints the sustained frame rate, frames dropped, mgmot's own per-stage
# latency percentiles (`mgmot run --stats-json`), an external end-to-end check from a UDP tap,
# each stage's share of the frame time, resident memory over the run and the load average.
#
#   scripts/bench_runtime.sh [--minutes N] [--scenario NAME] [--detector onnx|replay]
#                            [--backend onnxruntime|tract] [--model FILE] [--threads N]
#                            [--cot URL] [--out DIR]
#
# Defaults: 1 minute, leave_and_return (hover with a slow gimbal pan: swimmers in view, out of it
# and back all the time, so tracks, re-identification and messages flow through a whole soak;
# in mixed_mission_soak the whole-frame detector sees nothing for its first minutes), the int8
# model on onnxruntime (fetched from the PyPI
# wheel by scripts/detect_fetch_onnxruntime.sh; --backend tract needs nothing and uses the fp32
# model). --detector replay replays the simulator's detections instead of running the model:
# the rest of the pipeline without the cost of inference. --cot URL turns `[outputs.cot]` on
# (e.g. udp://239.2.3.1:6969 on loopback, or a TAK server's tcp://), to compare the frame path
# with and without it. Results go to out/bench_runtime/.
#
# Timing reference: the frame's capture timestamp (the simulator stamps the exposure on the
# autopilot clock; mgmot maps it onto its own clock with TIMESYNC). The scenario's
# `camera_time_offset_ms` and `telemetry_latency_ms` faults are zeroed for the benchmark, since
# they deliberately falsify exactly those timestamps; everything else (including the camera's
# 40 ms capture-to-delivery latency, which end to end includes) is the shipped scenario.
# `delivered_to_socket` starts instead when the frame reached mgmot's capture thread: mgmot's
# own latency, without the simulator's rendering, its simulated camera latency and its lag.
set -euo pipefail
cd "$(dirname "$0")/.."

minutes=1
scenario=leave_and_return
detector=onnx
backend=onnxruntime
model=""
threads=2
cot=""
out=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --minutes) minutes="$2"; shift 2 ;;
        --scenario) scenario="$2"; shift 2 ;;
        --detector) detector="$2"; shift 2 ;;
        --backend) backend="$2"; shift 2 ;;
        --model) model="$2"; shift 2 ;;
        --threads) threads="$2"; shift 2 ;;
        --cot) cot="$2"; shift 2 ;;
        --out) out="$2"; shift 2 ;;
        -h|--help) sed -n '2,24p' "$0"; exit 0 ;;
        *) echo "bench_runtime: unknown option $1 (see --help)" >&2; exit 2 ;;
    esac
done
case "$backend" in
    onnxruntime) model="${model:-models/mgmot-det-int8.onnx}" ;;
    tract) model="${model:-models/mgmot-det-fp32.onnx}" ;;
    *) echo "bench_runtime: --backend must be onnxruntime or tract" >&2; exit 2 ;;
esac
[[ "$detector" == onnx || "$detector" == replay ]] || {
    echo "bench_runtime: --detector must be onnx or replay" >&2; exit 2; }

out="${out:-out/bench_runtime/$(date -u +%Y%m%dT%H%M%SZ)-$scenario-$detector}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
echo "== building (release)" >&2
cargo build --release --quiet -p mgmot -p mgmot-sim --bins
MGMOT="$PWD/target/release/mgmot"
SIM="$PWD/target/release/mgmot-sim"
if [[ "$detector" == onnx && "$backend" == onnxruntime && -z "${ORT_DYLIB_PATH:-}" ]]; then
    ORT_DYLIB_PATH="$(bash scripts/detect_fetch_onnxruntime.sh)"
    export ORT_DYLIB_PATH
fi

free_port() { python3 -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
MGMOT_PORT="$(free_port)"
TAP_PORT="$(free_port)"
duration_s=$(( minutes * 60 + 20 ))

"$SIM" list --show "$scenario" \
    | sed -E 's/^(camera_time_offset_ms|telemetry_latency_ms) *=.*/\1 = 0.0/' >"$out/scenario.toml"

if [[ "$detector" == onnx ]]; then
    det_cfg="kind = \"onnx\"
model = \"$PWD/$model\"
backend = \"$backend\"
threads = $threads"
else
    echo "== simulated detections for the replay detector" >&2
    "$SIM" detections -s "$out/scenario.toml" --duration-s "$duration_s" \
        --width 1280 --height 720 --fps 30 -o "$out/dets.json" 2>>"$out/sim.log"
    det_cfg="kind = \"replay\"
detections = \"$out/dets.json\""
fi
cat >"$out/run.toml" <<EOF
[mavlink]
connection = "udpin:127.0.0.1:$MGMOT_PORT"
[frames]
source = "sim"
socket = "$out/frames.sock"
[detector]
$det_cfg
EOF
if [[ -n "$cot" ]]; then
    cat >>"$out/run.toml" <<EOF
[outputs.cot]
enabled = true
url = "$cot"
multicast_interface = "127.0.0.1"
EOF
fi

pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
}
trap cleanup EXIT

# The external tap: forwards sim <-> mgmot, and times every MGMOT_TRACK on arrival against the
# frame's capture stamp mapped onto this host's monotonic clock (the smallest arrival - stamp of
# the autopilot's ATTITUDE messages, whose stamp is their send time here).
python3 - "$TAP_PORT" "$MGMOT_PORT" "$out/tap.json" >"$out/tap.log" 2>&1 <<'PY' &
import json, signal, socket, struct, sys, time
listen, mgmot, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
up = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); up.bind(("127.0.0.1", listen))
down = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); down.bind(("127.0.0.1", 0))
up.setblocking(False); down.setblocking(False)
import selectors
sel = selectors.DefaultSelector(); sel.register(up, selectors.EVENT_READ); sel.register(down, selectors.EVENT_READ)
sim = None; offset_us = None; lat_ms = []; running = True
def stop(*_):
    global running; running = False
signal.signal(signal.SIGTERM, stop); signal.signal(signal.SIGINT, stop)
def frames(buf):
    i = 0
    while i + 12 <= len(buf):
        if buf[i] != 0xFD: i += 1; continue
        n, incompat = buf[i + 1], buf[i + 2]
        msgid = buf[i + 7] | buf[i + 8] << 8 | buf[i + 9] << 16
        payload = buf[i + 10:i + 10 + n] + bytes(64)
        yield msgid, payload
        i += 12 + n + (13 if incompat & 1 else 0)
while running:
    for key, _ in sel.select(0.2):
        s = key.fileobj
        try:
            data, addr = s.recvfrom(65536)
        except BlockingIOError:
            continue
        now_us = time.monotonic_ns() // 1000
        if s is up:
            sim = addr; down.sendto(data, ("127.0.0.1", mgmot))
            for msgid, p in frames(data):
                if msgid == 30:  # ATTITUDE: time_boot_ms first
                    o = now_us - struct.unpack_from("<I", p)[0] * 1000
                    offset_us = o if offset_us is None else min(offset_us, o)
        else:
            if sim: up.sendto(data, sim)
            for msgid, p in frames(data):
                if msgid == 43000 and offset_us is not None:  # MGMOT_TRACK: time_usec first
                    lat_ms.append((now_us - (struct.unpack_from("<Q", p)[0] + offset_us)) / 1000)
def pct(v, q):
    v = sorted(v); return v[min(len(v) - 1, int(q * len(v)))] if v else None
json.dump({"count": len(lat_ms), "p50_ms": pct(lat_ms, .5), "p95_ms": pct(lat_ms, .95),
           "p99_ms": pct(lat_ms, .99), "max_ms": max(lat_ms) if lat_ms else None}, open(out, "w"))
PY
tap_pid=$!
pids+=("$tap_pid")

what="$detector"
[[ "$detector" == onnx ]] && what="onnx: $backend, $(basename "$model"), $threads threads"
echo "== mgmot-sim run $scenario, real time, 1280x720 @ 30 fps; mgmot run ($what) for $minutes min" >&2
"$SIM" run -s "$out/scenario.toml" --realtime --duration-s "$duration_s" \
    --width 1280 --height 720 --fps 30 \
    --mavlink "udpout:127.0.0.1:$TAP_PORT" --frames "unix:$out/frames.sock" 2>"$out/sim.log" &
sim_pid=$!
pids+=("$sim_pid")
RUST_LOG="${RUST_LOG:-info}" "$MGMOT" run --config "$out/run.toml" --stats-json "$out/stats.json" \
    2>"$out/mgmot.log" &
mgmot_pid=$!
pids+=("$mgmot_pid")

# RSS and load every 10 s.
echo "t_s,rss_kib,load1" >"$out/rss.csv"
start=$(date +%s)
end=$(( start + minutes * 60 ))
while (( $(date +%s) < end )); do
    sleep 10
    kill -0 "$mgmot_pid" 2>/dev/null || { echo "mgmot exited early; see $out/mgmot.log" >&2; break; }
    rss=$(awk '/^VmRSS/ {print $2}' "/proc/$mgmot_pid/status" 2>/dev/null || echo "")
    echo "$(( $(date +%s) - start )),$rss,$(cut -d' ' -f1 /proc/loadavg)" >>"$out/rss.csv"
done
kill -TERM "$mgmot_pid" 2>/dev/null || true
wait "$mgmot_pid" || echo "mgmot exit status $?" >&2
sleep 1
kill -TERM "$tap_pid" 2>/dev/null || true
wait "$tap_pid" 2>/dev/null || true
kill "$sim_pid" 2>/dev/null || true
wait "$sim_pid" 2>/dev/null || true

[[ -s "$out/stats.json" ]] || { echo "no stats written; see $out/mgmot.log" >&2; exit 1; }
python3 - "$out" "$detector" <<'PY'
import csv, json, sys
out, detector = sys.argv[1], sys.argv[2]
s = json.load(open(f"{out}/stats.json"))
tap = json.load(open(f"{out}/tap.json")) if __import__("os").path.exists(f"{out}/tap.json") else {}
rows = list(csv.DictReader(open(f"{out}/rss.csv")))
lat = s["latency"]
frame_us = 1e6 / 30
fps = s["frames_processed"] / (s["active_us"] / 1e6) if s["active_us"] else 0
ms = lambda us: f"{us / 1000:.1f}"
print(f"results in {out}")
print(f"frames: {s['frames_captured']} captured, {s['frames_processed']} processed, "
      f"{s['frames_dropped']} dropped in the newest-frame slot, {s['frames_without_pose']} without pose, "
      f"{s['detector_errors']} detector errors, {s['track_messages']} MGMOT_TRACK, {s['messages_dropped']} messages dropped")
print(f"sustained rate: {fps:.1f} frames/s processed (source: 30 frames/s)")
print("latency (ms)         p50     p95     p99     max    mean  share of 33.3 ms frame time")
for name, st in lat.items():
    share = f"{100 * st['mean_us'] / frame_us:5.1f} %" if name not in ("frame_age", "slot_wait", "end_to_end", "delivered_to_socket", "send") else ""
    print(f"  {name:16s} {ms(st['p50_us']):>7s} {ms(st['p95_us']):>7s} {ms(st['p99_us']):>7s} {ms(st['max_us']):>7s} {ms(st['mean_us']):>7s}  {share}")
if "processing" in lat:
    inference = lat.get("detect_inference", {}).get("mean_us", 0) if detector == "onnx" else 0
    rest = lat["processing"]["mean_us"] - inference
    print(f"everything except the model run: {rest / 1000:.2f} ms mean = {100 * rest / frame_us:.1f} % of the frame time")
if tap.get("count"):
    print(f"external tap, capture stamp -> MGMOT_TRACK received: p50 {tap['p50_ms']:.1f}, p95 {tap['p95_ms']:.1f}, "
          f"p99 {tap['p99_ms']:.1f}, max {tap['max_ms']:.1f} ms ({tap['count']} messages)")
if rows:
    r = [(int(x["t_s"]), int(x["rss_kib"]) if x["rss_kib"] else None, float(x["load1"])) for x in rows]
    r = [x for x in r if x[1] is not None]
    if r:
        first, mid, last = r[0], r[len(r) // 2], r[-1]
        print(f"RSS: {first[1] / 1024:.1f} MiB at {first[0]} s, {mid[1] / 1024:.1f} MiB at {mid[0]} s, "
              f"{last[1] / 1024:.1f} MiB at {last[0]} s (max {max(x[1] for x in r) / 1024:.1f} MiB)")
        # Growth: least-squares slope over the run after its first minute (warm-up: the
        # allocator's arenas, ONNX Runtime's buffers and the tracker's first tracks).
        w = [x for x in r if x[0] >= 60] or r
        if len(w) >= 3:
            mt = sum(x[0] for x in w) / len(w); mr = sum(x[1] for x in w) / len(w)
            slope = sum((x[0] - mt) * (x[1] - mr) for x in w) / max(1e-9, sum((x[0] - mt) ** 2 for x in w))
            print(f"RSS slope after the first minute: {slope * 60 / 1024:+.2f} MiB/min "
                  f"(min {min(x[1] for x in w) / 1024:.1f}, max {max(x[1] for x in w) / 1024:.1f} MiB)")
        loads = [x[2] for x in r]
        print(f"load average (1 min): {loads[0]:.2f} at start, {loads[len(loads) // 2]:.2f} middle, "
              f"{loads[-1]:.2f} end, mean {sum(loads) / len(loads):.2f} (2 cores)")
PY
