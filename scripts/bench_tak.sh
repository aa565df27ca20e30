#!/usr/bin/env bash
# The TAK bench: mgmot streams Cursor-on-Target events to a real TAK server (FreeTAKServer
# 2.2.1, PyPI) and a real TAK client library (pytak 7.6.1) connected to that server receives
# them. Measures events lost between mgmot and the client, and the latency from an event's
# creation (its `time`, set right after the tracker step) to its arrival at the client; checks
# every received event against the CoT event schema.
#
#   scripts/bench_tak.sh [--duration-s 60] [--rate-hz 1] [--scenario calm_baseline]
#                        [--bin-dir target/release] [--out out/bench_tak]
#
# First run: creates .venv-tak (FreeTAKServer with its OpenTelemetry pins, pytak; about 30 s).
# FreeTAKServer writes under /opt/fts and /var/log and binds its web API to 0.0.0.0, all
# hard-coded; so the whole bench runs in a private mount and network namespace (`unshare`;
# root, or unprivileged user namespaces): tmpfs over /opt and /var/log, loopback only. Nothing
# on this machine is touched and nothing is reachable from outside.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/lib/fts.sh
source scripts/lib/fts.sh

duration=60 rate=1 scenario=calm_baseline bin=target/release out=out/bench_tak inside=0
while [ $# -gt 0 ]; do
  case "$1" in
    --duration-s) duration="$2"; shift 2 ;;
    --rate-hz) rate="$2"; shift 2 ;;
    --scenario) scenario="$2"; shift 2 ;;
    --bin-dir) bin="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --inside) inside=1; shift ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    *) echo "bench_tak: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
for b in mgmot mgmot-sim; do
  [ -x "$bin/$b" ] || { echo "bench_tak: $bin/$b is missing: cargo build --release" >&2; exit 1; }
done

if [ "$inside" = 0 ]; then
  fts_venv
  command -v unshare >/dev/null || { echo "bench_tak: needs unshare (util-linux)" >&2; exit 1; }
  flags=(--mount --net --propagation private)
  [ "$(id -u)" -eq 0 ] || flags=(--user --map-root-user "${flags[@]}")
  mkdir -p "$out"
  exec unshare "${flags[@]}" bash "$0" --inside --duration-s "$duration" --rate-hz "$rate" \
    --scenario "$scenario" --bin-dir "$bin" --out "$out"
fi

# --- inside the namespace ---
fts_namespace_setup
out="$(cd "$out" && pwd)"
rm -f "$out"/*.jsonl "$out"/*.json "$out"/*.log "$out"/*.toml
py=.venv-tak/bin/python

cleanup() { kill "${client:-}" "${mgmot_pid:-}" 2>/dev/null || true; fts_stop; }
trap cleanup EXIT
fts_start bench_tak "$out/fts.log" 30

echo "== pytak client on tcp://127.0.0.1:8087"
$py scripts/bench_tak_client.py --url tcp://127.0.0.1:8087 --out "$out/received.jsonl" \
  --ready "$out/client.ready" > "$out/client.log" 2>&1 &
client=$!
for _ in $(seq 1 40); do [ -f "$out/client.ready" ] && break; sleep 0.25; done
[ -f "$out/client.ready" ] || { echo "bench_tak: the pytak client did not connect (see $out/client.log)" >&2; exit 1; }
sleep 1

echo "== mgmot-sim ($scenario, ${duration} s real time) -> mgmot run ([outputs.cot] tcp://127.0.0.1:8087 at ${rate} Hz)"
"$bin/mgmot-sim" detections --scenario "$scenario" --duration-s "$duration" -o "$out/dets.json" > "$out/detections.log" 2>&1
port=$(python3 -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
cat > "$out/mgmot.toml" <<TOML
[mavlink]
connection = "udpin:127.0.0.1:$port"
[frames]
source = "sim"
socket = "$out/frames.sock"
[detector]
kind = "replay"
detections = "$out/dets.json"
[outputs.cot]
enabled = true
url = "tcp://127.0.0.1:8087"
rate_hz = $rate
callsign = "mgmot-bench"
TOML
"$bin/mgmot" check-config "$out/mgmot.toml" >/dev/null
"$bin/mgmot" run --config "$out/mgmot.toml" --stats-json "$out/stats.json" > "$out/mgmot.log" 2>&1 &
mgmot_pid=$!
"$bin/mgmot-sim" run --scenario "$scenario" --duration-s "$duration" --realtime \
  --mavlink "udpout:127.0.0.1:$port" --frames "unix:$out/frames.sock" > "$out/sim.log" 2>&1
for _ in $(seq 1 50); do kill -0 $mgmot_pid 2>/dev/null || break; sleep 0.2; done
kill $mgmot_pid 2>/dev/null || true
wait $mgmot_pid 2>/dev/null || true
# What is in flight through the server arrives within a second or two.
sleep 3
kill -TERM $client 2>/dev/null || true
wait $client 2>/dev/null || true
$py scripts/bench_tak_report.py "$out/received.jsonl" "$out/stats.json" --json "$out/report.json"
