#!/usr/bin/env bash
# Checks systemd/mgmot.service (run by scripts/test.sh, about a second):
#   - `systemd-analyze verify`: clean, but for the one line saying that the unit's ExecStart
#     binary (/usr/local/bin/mgmot) is not installed on this machine; and fully clean on a copy
#     whose ExecStart names the freshly built target/release/mgmot;
#   - `systemd-analyze security --offline=true`: overall exposure at most $MAX_EXPOSURE.
# Needs systemd-analyze from systemd >= 250 (scripts/setup.sh installs the `systemd` package).
set -euo pipefail
cd "$(dirname "$0")/.."
MAX_EXPOSURE="${MAX_EXPOSURE:-2.0}"
unit=systemd/mgmot.service
exec_bin=/usr/local/bin/mgmot

if ! command -v systemd-analyze >/dev/null 2>&1; then
  echo "check_unit: systemd-analyze not found: install the systemd package (apt-get install systemd; scripts/setup.sh does)" >&2
  exit 1
fi
grep -qx "ExecStart=$exec_bin run --config /etc/mgmot/mgmot.toml" "$unit" || {
  echo "check_unit: $unit: ExecStart is not '$exec_bin run --config /etc/mgmot/mgmot.toml' (scripts/install.sh and tests/service_notify.rs rely on it)" >&2
  exit 1; }

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# The unit as it is: only the missing binary may be reported.
systemd-analyze verify "$unit" >"$tmp/verify.out" 2>&1 || true
if grep -v -x "mgmot.service: Command $exec_bin is not executable: No such file or directory" "$tmp/verify.out" | grep -q .; then
  echo "check_unit: systemd-analyze verify $unit:" >&2
  cat "$tmp/verify.out" >&2
  exit 1
fi
# A copy starting the built binary: no output at all.
bin="$PWD/target/release/mgmot"
[ -x "$bin" ] || bin="$(command -v true)"
sed "s|^ExecStart=$exec_bin |ExecStart=$bin |" "$unit" >"$tmp/mgmot.service"
if ! systemd-analyze verify "$tmp/mgmot.service" >"$tmp/verify.out" 2>&1 || [ -s "$tmp/verify.out" ]; then
  echo "check_unit: systemd-analyze verify (ExecStart=$bin):" >&2
  cat "$tmp/verify.out" >&2
  exit 1
fi

if ! systemd-analyze security --offline=true "$unit" >"$tmp/security.out" 2>&1; then
  echo "check_unit: systemd-analyze security --offline=true failed (needs systemd >= 250):" >&2
  cat "$tmp/security.out" >&2
  exit 1
fi
level="$(sed -n 's/.*Overall exposure level for mgmot\.service: \([0-9.]*\).*/\1/p' "$tmp/security.out")"
if [ -z "$level" ]; then
  echo "check_unit: no 'Overall exposure level' in the output of systemd-analyze security:" >&2
  cat "$tmp/security.out" >&2
  exit 1
fi
if awk -v l="$level" -v m="$MAX_EXPOSURE" 'BEGIN { exit !(l > m) }'; then
  echo "check_unit: exposure level $level is above $MAX_EXPOSURE:" >&2
  grep '✗' "$tmp/security.out" >&2 || true
  exit 1
fi
echo "check_unit: $unit verifies clean; exposure level $level (at most $MAX_EXPOSURE)"
