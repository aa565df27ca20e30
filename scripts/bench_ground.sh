#!/usr/bin/env bash
# The ground-picture bench: the whole chain from two simulated drones to a TAK client, with the
# real outside components (mavlink-router, FreeTAKServer 2.2.1, pytak 7.6.1):
#
#   mgmot-sim --vehicle 0 (sys 1) <-> router "drone 1" (127.0.1.1) <-> mgmot run (system_id 1)
#   mgmot-sim --vehicle 1 (sys 2) <-> router "drone 2" (127.0.2.1) <-> mgmot run (system_id 2)
#   each drone router's gcs endpoint (the "radio") <-> ground router (127.0.0.1) <-> mgmot ground
#   mgmot ground --cot tcp://127.0.0.1:8087 -> FreeTAKServer -> pytak client (records all)
#
#   scripts/bench_ground.sh [--duration-s 120] [--scenario two_drones|two_drones_abreast]
#                           [--seed N] [--size 640x360] [--bin-dir target/release]
#                           [--out out/bench_ground] [--router PATH_TO_mavlink-routerd]
#
# Each drone router is firmware-config/mavlink-router/main.conf with the UART replaced by a UDP
# server for the simulator (14555) and no TCP server: gcs = UDP server on 14550, mgmot = UDP
# normal to 14551 (mgmot run udpin). Each drone has its own loopback address, so both keep the
# shipped ports. The ground router has a UDP server on 127.0.0.1:14550 for mgmot ground
# (`--connection udpout:127.0.0.1:14550`: its GCS heartbeat makes the router learn it) and one
# normal endpoint per drone to that drone's 14550, the radio link.
# Routing: mgmot run counts another system's autopilot messages as spoofing, so each drone
# must get only its own autopilot's telemetry. mavlink-router forwards a broadcast message to
# every endpoint but the one it came from, so the ground router would relay drone 1's telemetry
# up drone 2's radio. The filter sits where the radios meet: on the ground router each drone
# endpoint has `AllowSrcSysOut = 255`, only the ground station's messages go up a radio (as on
# real radios, which should not carry one drone's stream to the other). The drone routers stay
# as shipped. The report checks it: each mgmot run's link.telemetry_from_others must be 0.
#
# Measured (bench_ground_report.py): fused CoT events the ground made and sent (its
# --stats-json) against the mgmot.ground.* events the pytak client received through the
# server, by (uid, time); the ground's connection to the server is also tapped (a packet socket
# on the namespace's loopback: passive) to name any missing event and split the latency from an
# event's `time` into ground -> wire and wire -> client. Every received event is checked against
# the CoT event schema. Fails (exit 1) when the ground heard other than 2 drones, an event is
# lost, the latency p95 exceeds 1 s, an event fails the schema, no fused track reached the
# client, or a drone's mgmot run got another system's telemetry. Logs, configs and
# report.json stay in --out.
#
# --seed N flies another seed than the scenario's (mgmot-sim --seed; e.g. the validation seeds
# 606-1515 of docs/ground.md). --size WxH renders both cameras smaller than the scenario's
# 1280x720 (default 640x360, as tests/ground.rs: two renderers on a 2-core machine).
# --router PATH: mavlink-routerd (else $MAVLINK_ROUTERD, else the one on PATH).
# First run: creates .venv-tak as scripts/bench_tak.sh does. The whole bench runs in a private
# mount, network and PID namespace (`unshare`; root or unprivileged user namespaces):
# FreeTAKServer writes /opt/fts and /var/log and binds 0.0.0.0, so tmpfs over /opt and
# /var/log, loopback only; every process of the bench ends with it.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/lib/fts.sh
source scripts/lib/fts.sh

duration=120 scenario=two_drones bin=target/release out=out/bench_ground seed="" size=640x360
router="${MAVLINK_ROUTERD:-}" inside=0
while [ $# -gt 0 ]; do
  case "$1" in
    --duration-s) duration="$2"; shift 2 ;;
    --scenario) scenario="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    --bin-dir) bin="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --router) router="$2"; shift 2 ;;
    --inside) inside=1; shift ;;
    -h|--help) sed -n '2,45p' "$0"; exit 0 ;;
    *) echo "bench_ground: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
case "$scenario" in
  two_drones|two_drones_abreast) ;;
  *) echo "bench_ground: --scenario must have two vehicles: two_drones or two_drones_abreast" >&2; exit 2 ;;
esac
case "$size" in
  [0-9]*x[0-9]*) width=${size%x*} height=${size#*x} ;;
  *) echo "bench_ground: --size WxH, e.g. 640x360" >&2; exit 2 ;;
esac
for b in mgmot mgmot-sim; do
  [ -x "$bin/$b" ] || { echo "bench_ground: $bin/$b is missing: cargo build --release" >&2; exit 1; }
done
if [ -z "$router" ]; then router=$(command -v mavlink-routerd || true); fi
if [ -z "$router" ] || [ ! -x "$router" ]; then
  cat >&2 <<'EOF'
bench_ground: mavlink-routerd not found: pass --router PATH, set MAVLINK_ROUTERD or put it on PATH.
  Build it (about 30 s): git clone --recurse-submodules https://github.com/mavlink-router/mavlink-router
  cd mavlink-router && pip install meson ninja && meson setup build . --buildtype=release && ninja -C build
  then: --router mavlink-router/build/src/mavlink-routerd (docs/sitl-bench.md, step 2).
EOF
  exit 2
fi
router=$(cd "$(dirname "$router")" && pwd)/$(basename "$router")

if [ "$inside" = 0 ]; then
  fts_venv
  command -v unshare >/dev/null || { echo "bench_ground: needs unshare (util-linux)" >&2; exit 1; }
  # --kill-child: should unshare itself be killed, the bench's PID 1 goes with it, and the
  # kernel ends every process of the namespace.
  flags=(--mount --net --pid --kill-child --mount-proc --propagation private)
  [ "$(id -u)" -eq 0 ] || flags=(--user --map-root-user "${flags[@]}")
  mkdir -p "$out"
  args=(--inside --duration-s "$duration" --scenario "$scenario" --size "$size" --bin-dir "$bin"
        --out "$out" --router "$router")
  [ -z "$seed" ] || args+=(--seed "$seed")
  unshare "${flags[@]}" bash "$0" "${args[@]}" &
  ns=$!
  # unshare ignores SIGINT and SIGTERM while it waits: hand them to the bench's PID 1, which
  # stops everything cleanly (its EXIT trap).
  # shellcheck disable=SC2317  # called by the traps
  forward() { local inner; inner=$(pgrep -P "$ns" || true); [ -z "$inner" ] || kill -TERM "$inner" 2>/dev/null || true; }
  trap forward INT TERM
  rc=0
  wait "$ns" || rc=$?
  while kill -0 "$ns" 2>/dev/null; do rc=0; wait "$ns" || rc=$?; done
  exit "$rc"
fi

# --- inside the namespaces (this shell is PID 1: when it ends, the kernel ends the rest) ---
fts_namespace_setup
out="$(cd "$out" && pwd)"
rm -rf "$out"/*.jsonl "$out"/*.json "$out"/*.log "$out"/*.toml "$out"/*.conf "$out"/*.sock \
  "$out"/*.ready "$out"/dets*_gt "$out"/truth* "$out"/empty.d
py=.venv-tak/bin/python
seed_args=()
[ -z "$seed" ] || seed_args=(--seed "$seed")

pids=()
# shellcheck disable=SC2317  # called by the EXIT trap
cleanup() {
  local p
  trap '' INT TERM
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  fts_stop
  wait 2>/dev/null || true
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

echo "== mgmot-sim detections ($scenario${seed:+, seed $seed}, ${duration} s, ${width}x${height}) for both vehicles"
for k in 1 2; do
  "$bin/mgmot-sim" detections --scenario "$scenario" --vehicle $((k - 1)) --duration-s "$duration" \
    --width "$width" --height "$height" ${seed_args[@]+"${seed_args[@]}"} -o "$out/dets$k.json" \
    > "$out/detections$k.log" 2>&1
done

fts_start bench_ground "$out/fts.log" 45

echo "== pytak client on tcp://127.0.0.1:8087; tap on the loopback (TCP to 8087)"
$py scripts/bench_tak_client.py --url tcp://127.0.0.1:8087 --out "$out/received.jsonl" \
  --ready "$out/client.ready" > "$out/client.log" 2>&1 &
client=$!
pids+=("$client")
for _ in $(seq 1 40); do [ -f "$out/client.ready" ] && break; sleep 0.25; done
[ -f "$out/client.ready" ] || { echo "bench_ground: the pytak client did not connect (see $out/client.log)" >&2; exit 1; }
$py scripts/bench_ground_report.py tap --port 8087 --out "$out/sent_tap.jsonl" \
  --ready "$out/tap.ready" > "$out/tap.log" 2>&1 &
tap=$!
pids+=("$tap")
for _ in $(seq 1 40); do [ -f "$out/tap.ready" ] && break; sleep 0.25; done
[ -f "$out/tap.ready" ] || { echo "bench_ground: the tap did not start (see $out/tap.log)" >&2; exit 1; }
sleep 1

echo "== mavlink-router: drone 1 (127.0.1.1), drone 2 (127.0.2.1), ground (127.0.0.1)"
mkdir -p "$out/empty.d"  # -d: no /etc/mavlink-router/config.d of this machine
for k in 1 2; do
  cat > "$out/router_drone$k.conf" <<EOF
# Drone $k's companion: firmware-config/mavlink-router/main.conf, the autopilot UART replaced by
# a UDP server for mgmot-sim --vehicle $((k - 1)), no TCP server.
[General]
TcpServerPort = 0
ReportStats = false
MavlinkDialect = auto

[UdpEndpoint autopilot]
Mode = Server
Address = 127.0.$k.1
Port = 14555

# The radio to the ground: the ground router's drone$k endpoint sends here.
[UdpEndpoint gcs]
Mode = Server
Address = 127.0.$k.1
Port = 14550

[UdpEndpoint mgmot]
Mode = Normal
Address = 127.0.$k.1
Port = 14551
EOF
  "$router" -c "$out/router_drone$k.conf" -d "$out/empty.d" > "$out/router_drone$k.log" 2>&1 &
  pids+=("$!")
done
cat > "$out/router_ground.conf" <<EOF
# The ground: one endpoint per drone's radio, a server for the ground station (mgmot ground).
[General]
TcpServerPort = 0
ReportStats = false
MavlinkDialect = auto

[UdpEndpoint gcs]
Mode = Server
Address = 127.0.0.1
Port = 14550

# Only the ground station's messages (system 255) go up a radio: a drone's telemetry is not
# relayed to the other drone.
[UdpEndpoint drone1]
Mode = Normal
Address = 127.0.1.1
Port = 14550
AllowSrcSysOut = 255

[UdpEndpoint drone2]
Mode = Normal
Address = 127.0.2.1
Port = 14550
AllowSrcSysOut = 255
EOF
"$router" -c "$out/router_ground.conf" -d "$out/empty.d" > "$out/router_ground.log" 2>&1 &
pids+=("$!")
sleep 1

echo "== mgmot ground (udpout:127.0.0.1:14550, --cot tcp://127.0.0.1:8087)"
"$bin/mgmot" ground --connection udpout:127.0.0.1:14550 --http 127.0.0.1:18080 \
  --record "$out/ground.jsonl" --cot tcp://127.0.0.1:8087 --stats-json "$out/ground_stats.json" \
  > "$out/ground.log" 2>&1 &
ground=$!
pids+=("$ground")
# Its heartbeat (1 Hz) goes through the ground router up both radios: the drone routers' gcs
# endpoints learn where the ground is before the drones fly.
sleep 3

runs=()
for k in 1 2; do
  cat > "$out/run$k.toml" <<TOML
[mavlink]
connection = "udpin:127.0.$k.1:14551"
system_id = $k
[frames]
source = "sim"
socket = "$out/frames$k.sock"
[detector]
kind = "replay"
detections = "$out/dets$k.json"
TOML
  "$bin/mgmot" check-config "$out/run$k.toml" >/dev/null
  "$bin/mgmot" run --config "$out/run$k.toml" --stats-json "$out/run${k}_stats.json" \
    > "$out/run$k.log" 2>&1 &
  runs+=("$!")
  pids+=("$!")
done

echo "== mgmot-sim run, both vehicles together ($scenario, ${duration} s real time)"
sims=()
# Both fly on the simulator's UTC from the scenario's start: start them together.
for k in 1 2; do
  "$bin/mgmot-sim" run --scenario "$scenario" --vehicle $((k - 1)) --duration-s "$duration" --realtime \
    --width "$width" --height "$height" ${seed_args[@]+"${seed_args[@]}"} \
    --mavlink "udpout:127.0.$k.1:14555" --frames "unix:$out/frames$k.sock" \
    --truth-out "$out/truth$k" > "$out/sim$k.log" 2>&1 &
  sims+=("$!")
  pids+=("$!")
done
sim_rc=0
for p in "${sims[@]}"; do wait "$p" || sim_rc=$?; done
[ "$sim_rc" = 0 ] || echo "bench_ground: a simulator failed (exit $sim_rc; see $out/sim*.log)" >&2
for p in "${runs[@]}"; do
  for _ in $(seq 1 50); do kill -0 "$p" 2>/dev/null || break; sleep 0.2; done
  kill -INT "$p" 2>/dev/null || true
  wait "$p" 2>/dev/null || true
done
# The ground's last updates, then a clean stop: it sends what is queued and closes its
# connection, then writes its stats.
sleep 2
kill -TERM "$ground" 2>/dev/null || true
wait "$ground" || echo "bench_ground: mgmot ground exited $? (see $out/ground.log)" >&2
# What is in flight through the server arrives within a second or two.
sleep 3
kill -TERM "$client" "$tap" 2>/dev/null || true
wait "$client" "$tap" 2>/dev/null || true
rc=0
$py scripts/bench_ground_report.py report "$out" --json "$out/report.json" || rc=$?
echo "== logs, configs and report.json in $out"
exit "$rc"
