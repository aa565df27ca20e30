#!/usr/bin/env bash
# Installs mgmot as a systemd service (docs/deployment.md), or removes it.
#
#   scripts/install.sh [--prefix DIR] [--no-build] [--binary FILE] [--tract | --ort-lib FILE]
#                      [--no-system]
#   scripts/install.sh --uninstall [--purge] [--prefix DIR] [--no-system]
#
# Installs (DESTDIR, when set, is put in front of every path, for packaging and tests):
#   PREFIX/bin/mgmot                          stripped binary (.gnu_debuglink -> mgmot.debug)
#   PREFIX/bin/mgmot.debug                    its debug info, for gdb and backtraces
#   PREFIX/share/mgmot/models/*.onnx          the shipped detector (int8 and fp32)
#   PREFIX/lib/mgmot/libonnxruntime.so        ONNX Runtime (not with --tract)
#   PREFIX/share/doc/mgmot/README.md, PREFIX/share/doc/mgmot/docs/*.md
#   /etc/mgmot/mgmot.toml                     the configuration, only if there is none yet
#   /etc/mgmot/mgmot.example.toml             the shipped example, every key documented
#   /etc/systemd/system/mgmot.service         the unit
# and, unless --no-system: the `mgmot` system user (groups video, dialout), owner of the
# configuration's group, and `systemctl daemon-reload`. It does not enable or start the service.
#
# --prefix DIR      default /usr/local; the unit's ExecStart and the new configuration's model
#                   and library paths follow it.
# --no-build        install target/release/mgmot as it is (build it first as your user:
#                   `cargo build --release`; root's PATH often has no cargo).
# --binary FILE     install this binary instead (a cross-built one: set OBJCOPY and STRIP to
#                   the target's binutils, e.g. aarch64-linux-gnu-objcopy).
# --tract           no ONNX Runtime: a new configuration uses backend = "tract" and the fp32
#                   model (pure Rust, slower).
# --ort-lib FILE    the libonnxruntime.so to install (default: $ORT_DYLIB_PATH, else the one
#                   scripts/detect_fetch_onnxruntime.sh fetches from PyPI).
# --no-system       files only: no user, no chown, no systemctl (tests, packaging).
# --uninstall       removes what the installer installed; keeps /etc/mgmot/mgmot.toml and the
#                   flight data in /var/lib/mgmot (and the user) unless --purge.
set -euo pipefail
cd "$(dirname "$0")/.."

prefix=/usr/local
build=1
binary=target/release/mgmot
tract=0
ort_lib="${ORT_DYLIB_PATH:-}"
system=1
uninstall=0
purge=0
while [ $# -gt 0 ]; do
  case "$1" in
    --prefix) prefix="${2:?--prefix needs a directory}"; shift ;;
    --prefix=*) prefix="${1#*=}" ;;
    --no-build) build=0 ;;
    --binary) binary="${2:?--binary needs a file}"; build=0; shift ;;
    --tract) tract=1 ;;
    --ort-lib) ort_lib="${2:?--ort-lib needs a file}"; shift ;;
    --no-system) system=0 ;;
    --uninstall) uninstall=1 ;;
    --purge) purge=1 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "install: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
  shift
done
case "$prefix" in
  /*) prefix="${prefix%/}" ;;
  *) echo "install: --prefix must be an absolute path: $prefix" >&2; exit 2 ;;
esac
if [ "$purge" = 1 ] && [ "$uninstall" = 0 ]; then
  echo "install: --purge goes with --uninstall" >&2; exit 2
fi

root="${DESTDIR:-}"
root="${root%/}"
bindir="$root$prefix/bin"
sharedir="$root$prefix/share/mgmot"
libdir="$root$prefix/lib/mgmot"
docdir="$root$prefix/share/doc/mgmot"
etcdir="$root/etc/mgmot"
unitdir="$root/etc/systemd/system"
statedir="$root/var/lib/mgmot"
models=(mgmot-det-int8.onnx mgmot-det-fp32.onnx mgmot-det-tiles-int8.onnx)

if [ "$system" = 1 ] && [ "$(id -u)" -ne 0 ]; then
  echo "install: run as root (sudo), or with --no-system for the files only" >&2
  exit 1
fi

if [ "$uninstall" = 1 ]; then
  if [ "$system" = 1 ] && command -v systemctl >/dev/null 2>&1; then
    systemctl disable --now mgmot.service 2>/dev/null || true
  fi
  rm -f "$bindir/mgmot" "$bindir/mgmot.debug" "$unitdir/mgmot.service" \
    "$libdir/libonnxruntime.so" "$docdir/README.md" "$docdir"/docs/*.md "$etcdir/mgmot.example.toml"
  for m in "${models[@]}"; do rm -f "$sharedir/models/$m"; done
  rmdir "$sharedir/models" "$sharedir" "$libdir" "$docdir/docs" "$docdir" 2>/dev/null || true
  if [ "$purge" = 1 ]; then
    rm -f "$etcdir/mgmot.toml"
    rmdir "$etcdir" 2>/dev/null || true
    rm -rf "$statedir"
    if [ "$system" = 1 ] && id mgmot >/dev/null 2>&1; then
      userdel mgmot || echo "install: could not remove the mgmot user" >&2
    fi
    echo "mgmot removed, with its configuration, flight data and user"
  else
    echo "mgmot removed; kept: $etcdir/mgmot.toml, $statedir (--purge removes them)"
  fi
  if [ "$system" = 1 ] && command -v systemctl >/dev/null 2>&1; then
    systemctl daemon-reload
  fi
  exit 0
fi

# --- install ---
OBJCOPY="${OBJCOPY:-objcopy}"
STRIP="${STRIP:-strip}"
for tool in "$OBJCOPY" "$STRIP"; do
  command -v "$tool" >/dev/null 2>&1 || {
    echo "install: $tool not found (binutils: apt-get install binutils)" >&2; exit 1; }
done
if [ "$build" = 1 ]; then
  command -v cargo >/dev/null 2>&1 || {
    echo "install: cargo not found: build as your user (cargo build --release), then run this with --no-build" >&2
    exit 1; }
  cargo build --release --bin mgmot
fi
[ -x "$binary" ] || { echo "install: no binary at $binary (build it, or --binary FILE)" >&2; exit 1; }
if [ "$tract" = 0 ] && [ -z "$ort_lib" ]; then
  ort_lib="$(bash scripts/detect_fetch_onnxruntime.sh)" || {
    echo "install: could not fetch ONNX Runtime; pass --ort-lib FILE, or --tract to run without it" >&2
    exit 1; }
fi
if [ "$tract" = 0 ] && [ ! -f "$ort_lib" ]; then
  echo "install: no ONNX Runtime library at $ort_lib" >&2; exit 1
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
# Debug info split off (gdb finds mgmot.debug beside the binary through .gnu_debuglink).
"$OBJCOPY" --only-keep-debug "$binary" "$work/mgmot.debug"
cp "$binary" "$work/mgmot"
"$STRIP" --strip-debug --strip-unneeded "$work/mgmot"
(cd "$work" && "$OBJCOPY" --add-gnu-debuglink=mgmot.debug mgmot)

install -d -m 0755 "$bindir" "$sharedir/models" "$docdir" "$unitdir"
install -m 0755 "$work/mgmot" "$bindir/mgmot"
install -m 0644 "$work/mgmot.debug" "$bindir/mgmot.debug"
for m in "${models[@]}"; do install -m 0644 "models/$m" "$sharedir/models/$m"; done
install -m 0644 README.md "$docdir/README.md"
install -d -m 0755 "$docdir/docs"
install -m 0644 docs/*.md "$docdir/docs/"
if [ "$tract" = 0 ]; then
  install -d -m 0755 "$libdir"
  install -m 0644 "$ort_lib" "$libdir/libonnxruntime.so"
fi

# The unit and the configuration, with the paths of this prefix.
sed -e "s|/usr/local/|$prefix/|g" systemd/mgmot.service >"$work/mgmot.service"
sed -e "s|\"/usr/local/|\"$prefix/|g" systemd/mgmot.example.toml >"$work/mgmot.example.toml"
cp "$work/mgmot.example.toml" "$work/mgmot.toml"
if [ "$tract" = 1 ]; then
  sed -i -e 's|^backend = ".*"|backend = "tract"|' \
    -e 's|^model = "\(.*\)/mgmot-det-int8.onnx"|model = "\1/mgmot-det-fp32.onnx"|' \
    -e 's|^alternatives = |# alternatives = |' \
    -e 's|^ort_library = |# ort_library = |' "$work/mgmot.toml"
fi
install -m 0644 "$work/mgmot.service" "$unitdir/mgmot.service"
install -d -m 0755 "$etcdir"
install -m 0644 "$work/mgmot.example.toml" "$etcdir/mgmot.example.toml"
# The configuration holds the signing key: readable by root and the mgmot group only.
if [ -e "$etcdir/mgmot.toml" ]; then
  echo "install: keeping the existing $etcdir/mgmot.toml (the new example: mgmot.example.toml)"
else
  install -m 0640 "$work/mgmot.toml" "$etcdir/mgmot.toml"
fi

if [ "$system" = 1 ]; then
  for g in video dialout; do getent group "$g" >/dev/null || groupadd --system "$g"; done
  if id mgmot >/dev/null 2>&1; then
    usermod -a -G video,dialout mgmot
  else
    useradd --system --user-group --groups video,dialout --home-dir /var/lib/mgmot \
      --no-create-home --shell /usr/sbin/nologin --comment "mgmot onboard tracker" mgmot
  fi
  chgrp mgmot "$etcdir/mgmot.toml"
  systemctl daemon-reload
fi

size() { stat -c %s "$1"; }
echo "installed mgmot in $root$prefix: binary $(size "$bindir/mgmot") bytes (stripped; $(size "$binary") before), debug info $(size "$bindir/mgmot.debug") bytes"
echo "next: edit $etcdir/mgmot.toml ([mavlink].connection, [frames], signing key), check it with"
echo "  $prefix/bin/mgmot check-config /etc/mgmot/mgmot.toml"
echo "then: systemctl enable --now mgmot; journalctl -u mgmot -f"
