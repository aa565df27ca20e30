#!/usr/bin/env bash
# Installs what building and testing mgmot needs on a Debian machine, or stops with a clear
# message. Safe to run repeatedly. Sourced by demo.sh and test.sh.
set -euo pipefail

need_apt=()
command -v cargo >/dev/null 2>&1 || {
  echo "setup: cargo (Rust stable >= 1.85) is required: install it with rustup (https://rustup.rs) and re-run." >&2
  exit 1
}
command -v cc >/dev/null 2>&1 || need_apt+=(build-essential)
command -v python3 >/dev/null 2>&1 || need_apt+=(python3 python3-pip python3-venv)
command -v pkg-config >/dev/null 2>&1 || need_apt+=(pkg-config)
# scripts/check_unit.sh (systemd-analyze) and the installer test (objcopy, strip).
command -v systemd-analyze >/dev/null 2>&1 || need_apt+=(systemd)
command -v objcopy >/dev/null 2>&1 || need_apt+=(binutils)
# openssl: tests/runtime_cot.rs makes the certificates of its TLS server with it; unshare
# (util-linux): scripts/bench_tak.sh runs FreeTAKServer in its own namespaces
command -v openssl >/dev/null 2>&1 || need_apt+=(openssl)
command -v unshare >/dev/null 2>&1 || need_apt+=(util-linux)
# The permission tests run mgmot without CAP_DAC_OVERRIDE through capsh (tests/common).
command -v capsh >/dev/null 2>&1 || [ -x /usr/sbin/capsh ] || [ -x /sbin/capsh ] || need_apt+=(libcap2-bin)
# bindgen (used by the v4l crate) needs libclang.
compgen -G "/usr/lib/llvm-*/lib/libclang.so*" >/dev/null || compgen -G "/usr/lib/*-linux-gnu/libclang.so*" >/dev/null || need_apt+=(libclang-dev)

if [ ${#need_apt[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${need_apt[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  if ! command -v apt-get >/dev/null 2>&1; then
    echo "setup: apt-get not found; please install: ${need_apt[*]}" >&2
    exit 1
  fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

# A debug build of the workspace plus the Python tools takes about 8 GB; stop early and say so
# rather than failing in the middle of a link.
avail_kb="$(df -Pk . | awk 'NR==2 {print $4}')"
if [ -n "$avail_kb" ] && [ "$avail_kb" -lt $((8 * 1024 * 1024)) ] && [ ! -d target/debug ]; then
  echo "setup: only $((avail_kb / 1024)) MB free on $(df -P . | awk 'NR==2 {print $6}'); building needs about 8 GB. Free some space and re-run." >&2
  exit 1
fi
