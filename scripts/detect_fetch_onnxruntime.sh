#!/usr/bin/env bash
# Fetches the ONNX Runtime shared library for mgmot's `onnxruntime` backend
# from the `onnxruntime` wheel on PyPI (no system install, no root) and prints
# the path of libonnxruntime.so on stdout, ready for ORT_DYLIB_PATH:
#
#   export ORT_DYLIB_PATH="$(scripts/detect_fetch_onnxruntime.sh)"
#
# The wheel is cached in $MGMOT_ORT_CACHE (default ~/.cache/mgmot/onnxruntime);
# a second run reuses it. Needs python3 with pip (PyPI access on first run).
set -euo pipefail

VERSION="${MGMOT_ORT_VERSION:-1.24.4}"
CACHE="${MGMOT_ORT_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/mgmot/onnxruntime}"
DEST="$CACHE/$VERSION"

find_lib() {
    find "$DEST/extracted" -name 'libonnxruntime.so*' -type f 2>/dev/null | sort | head -n 1
}

lib="$(find_lib || true)"
if [[ -z "$lib" ]]; then
    mkdir -p "$DEST/wheel" "$DEST/extracted"
    echo "fetching onnxruntime==$VERSION wheel into $DEST" >&2
    python3 -m pip download --quiet --no-deps --only-binary=:all: \
        --dest "$DEST/wheel" "onnxruntime==$VERSION" >&2
    wheel="$(ls "$DEST"/wheel/onnxruntime-"$VERSION"-*.whl | head -n 1)"
    # A wheel is a zip file; only the shared library is needed.
    python3 - "$wheel" "$DEST/extracted" <<'PY'
import sys, zipfile
wheel, dest = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(wheel) as z:
    for name in z.namelist():
        if "/capi/libonnxruntime.so" in name:
            z.extract(name, dest)
PY
    lib="$(find_lib || true)"
fi
if [[ -z "$lib" ]]; then
    echo "no libonnxruntime.so found in the onnxruntime $VERSION wheel" >&2
    exit 1
fi
echo "$lib"
