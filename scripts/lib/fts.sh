# shellcheck shell=bash
# FreeTAKServer for the benches (sourced by scripts/bench_tak.sh and scripts/bench_ground.sh).
#
# FreeTAKServer 2.2.1 writes under /opt/fts and /var/log and binds its web API to 0.0.0.0, all
# hard-coded, so the benches run it inside a private mount and network namespace: `fts_venv`
# outside it, then `fts_namespace_setup` and `fts_start` inside it.

# The pinned venv .venv-tak (FreeTAKServer, pytak, lxml from PyPI); about 30 s the first time.
fts_venv() {
  if [ ! -x .venv-tak/bin/python ] || ! .venv-tak/bin/python -c "import FreeTAKServer, pytak, lxml" 2>/dev/null; then
    echo "== .venv-tak: FreeTAKServer 2.2.1 and pytak 7.6.1 (PyPI)"
    python3 -m venv .venv-tak
    # OpenTelemetry 1.24.0: with the newer release pip picks, FreeTAKServer's CoT services die
    # at start ("property 'span_exporter' of 'BatchSpanProcessor' object has no setter").
    .venv-tak/bin/pip install -q --disable-pip-version-check FreeTAKServer==2.2.1 \
      opentelemetry-api==1.24.0 opentelemetry-sdk==1.24.0 pytak==7.6.1 lxml==6.2.0
  fi
}

# Inside the new namespaces: the loopback up (with `ip`, or an ioctl where iproute2 is
# missing), and tmpfs over /opt and /var/log for FreeTAKServer's files.
fts_namespace_setup() {
  ip link set lo up 2>/dev/null || python3 - <<'PY'
import fcntl, socket, struct
s = socket.socket(); ifr = struct.pack("16sH", b"lo", 0)
flags = struct.unpack("16sH", fcntl.ioctl(s, 0x8913, ifr))[1]
fcntl.ioctl(s, 0x8914, struct.pack("16sH", b"lo", flags | 1))
PY
  mount -t tmpfs tmpfs /opt
  mount -t tmpfs tmpfs /var/log
  mkdir -p /opt/fts
}

# fts_start NAME LOG WAIT_S: starts FreeTAKServer on 127.0.0.1 (CoT TCP 8087) with its output in
# LOG, sets `fts` to its PID and waits up to WAIT_S seconds for 8087 to open; exits naming NAME
# (the bench) and LOG when it does not.
fts_start() {
  local name="$1" log="$2" wait_s="$3" i tries
  echo "== FreeTAKServer 2.2.1 on 127.0.0.1 (CoT TCP 8087)"
  (cd /opt/fts && FTS_FIRST_START=false exec "$OLDPWD/.venv-tak/bin/python" -m FreeTAKServer.controllers.services.FTS \
    -CoTIP 127.0.0.1 -SSLCoTIP 127.0.0.1 -DataPackageIP 127.0.0.1 -SSLDataPackageIP 127.0.0.1 \
    -RestAPIIP 127.0.0.1 -AutoStart True) > "$log" 2>&1 &
  fts=$!
  tries=$((wait_s * 2))
  for i in $(seq 1 "$tries"); do
    if .venv-tak/bin/python -c "import socket; socket.create_connection(('127.0.0.1', 8087), 0.5).close()" 2>/dev/null; then break; fi
    [ "$i" = "$tries" ] && { echo "$name: FreeTAKServer did not open 8087 in $wait_s s (see $log)" >&2; exit 1; }
    sleep 0.5
  done
  # A connection that sends nothing holds up other new connections for 60 s on FTS: the probe
  # above closed at once; give the server a moment to forget it.
  sleep 2
}

# Stops FreeTAKServer (its service processes first) if `fts_start` started it.
fts_stop() {
  if [ -n "${fts:-}" ]; then pkill -P "$fts" 2>/dev/null || true; kill "$fts" 2>/dev/null || true; fi
}
