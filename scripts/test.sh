#!/usr/bin/env bash
# The test command: installs what the tests need, then runs formatting and lint checks and the
# whole test suite (unit, property, integration over real sockets, real-data fixtures).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh

if [ ! -d ../shared/data/seadronessee ]; then
  echo "test: ../shared/data/seadronessee is missing: clone the repo next to the shared/ folder." >&2
  exit 1
fi

# Python cross-checks (py-motmetrics, pymavlink) run from a project virtualenv. The tests that
# need an outside tool (these, ONNX Runtime below) fail, naming it, when it is missing: none of
# them passes as a skip.
if [ ! -x .venv/bin/python3 ] || ! .venv/bin/python3 -c "import motmetrics, pymavlink, PIL, onnx, lxml" 2>/dev/null; then
  echo "== python venv for the cross-checks (.venv)"
  if ! python3 -m venv .venv 2>/dev/null; then
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq python3-venv >/dev/null
    python3 -m venv .venv
  fi
  .venv/bin/python3 -m pip install -q --disable-pip-version-check -r scripts/requirements-test.txt
fi
export PATH="$PWD/.venv/bin:$PATH"

# Debian's Chromium, headless: tests/review.rs opens `mgmot review`'s report in it (and fails,
# naming it, without it).
if ! command -v chromium >/dev/null 2>&1; then
  echo "== chromium (tests/review.rs, tests/ground.rs)"
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
fi

# ONNX Runtime (from the onnxruntime wheel on PyPI) for the tests that need it (the
# tract/onnxruntime parity and default-backend tests in tests/detect_cli.rs).
if [ -z "${ORT_DYLIB_PATH:-}" ]; then
  if ORT_DYLIB_PATH="$(bash scripts/detect_fetch_onnxruntime.sh)"; then
    export ORT_DYLIB_PATH
  else
    echo "test: could not fetch the onnxruntime wheel; the tests that need ONNX Runtime will fail, naming ORT_DYLIB_PATH" >&2
    unset ORT_DYLIB_PATH
  fi
fi

echo "== cargo fmt --check"
cargo fmt --all --check
echo "== cargo clippy"
# In the release profile: its build scripts (the MAVLink dialect's generator, bindgen) and proc
# macros are then the ones the demo's release build already compiled and ran, instead of a
# second, dev-profile set (clippy itself only checks, so the profile changes no lint).
cargo clippy --release --workspace --all-targets --quiet -- -D warnings
echo "== systemd unit: systemd-analyze verify, security exposure <= 2.0"
bash scripts/check_unit.sh
echo "== cargo test (release)"
# Release mode, on top of the demo's build when it ran first (as in CI): the dependencies'
# features are the same with the dev-dependencies (see Cargo.toml), so only the tests are
# compiled, instead of a second, debug build of everything (about 12 minutes on 2 cores).
# Overflow checks are on in release (Cargo.toml). The runtime's loopback tests drive the
# simulator binary this same build produces.
export MGMOT_SIM_BIN="$PWD/target/release/mgmot-sim"
# The loopback tests start a simulator and mgmot each; one test at a time keeps them within
# their real-time budgets on a 2-core machine.
export RUST_TEST_THREADS=1
# The fuzz targets (fuzz/README.md, tests/fuzz_decoders.rs) run inside the suite on a million
# generated inputs each (about 15 s in all; a separate `cargo test -p mgmot --test main` would
# resolve features for one package and rebuild mgmot). The seed comes from the commit, so each
# commit tries new inputs and a finding is reproducible with the printed seed.
export MGMOT_FUZZ_CASES=1000000
MGMOT_FUZZ_SEED="0x$(git rev-parse --short=15 HEAD 2>/dev/null || echo 6d676d6f7466757a)"
export MGMOT_FUZZ_SEED
MGMOT_FUZZ_SUMMARY="$(mktemp)"
export MGMOT_FUZZ_SUMMARY
trap 'rm -f "$MGMOT_FUZZ_SUMMARY"' EXIT
cargo test --workspace --release
echo "== fuzz: 1,000,000 generated inputs per target (MGMOT_FUZZ_SEED=$MGMOT_FUZZ_SEED)"
cat "$MGMOT_FUZZ_SUMMARY"
# train/'s data path without PyTorch: a rendered sequence laid out as SeaDronesSee and read back.
echo "== train/: the SeaDronesSee-layout data path (train/test_data.py)"
seq="$(mktemp -d)/seq"
"$MGMOT_SIM_BIN" render -s calm_baseline -o "$seq" --format jpg --every 150 --duration-s 40 2>/dev/null
.venv/bin/python3 train/test_data.py "$seq"
rm -rf "$(dirname "$seq")"
# The TAK bench: mgmot streams Cursor-on-Target to a real TAK server (FreeTAKServer 2.2.1 from
# PyPI, in its own namespaces) and a pytak client behind it must receive every event, each valid
# against the CoT event schema, p95 creation -> client <= 1 s (docs/tak.md).
echo "== TAK bench: mgmot -> FreeTAKServer -> pytak client, 30 s (scripts/bench_tak.sh)"
tak_out="$(mktemp -d)"
bash scripts/bench_tak.sh --duration-s 30 --bin-dir target/release --out "$tak_out/bench_tak"
rm -rf "$tak_out"
