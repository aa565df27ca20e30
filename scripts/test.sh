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

# The outside tools the tests use are fetched in the background (network and disk) while fmt,
# clippy and the test build below keep both cores busy; the job's log is printed if it fails.
#  - Python cross-checks (py-motmetrics, pymavlink) run from a project virtualenv, .venv. The
#    tests that need an outside tool (these, ONNX Runtime below) fail, naming it, when it is
#    missing: none of them passes as a skip.
#  - Debian's Chromium, headless: tests/review.rs opens `mgmot review`'s report in it and
#    tests/ground.rs the ground's live map (both fail, naming it, without it).
#  - .venv-tak: FreeTAKServer and pytak for the TAK bench at the end (scripts/lib/fts.sh).
# apt-get runs in this one job only, so no two installs wait on dpkg's lock.
prepare() {
  local SUDO="" apt=()
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  command -v chromium >/dev/null 2>&1 || apt+=(chromium)
  python3 -c "import venv, ensurepip" 2>/dev/null || apt+=(python3-venv)
  if [ ${#apt[@]} -gt 0 ]; then
    echo "== apt-get install ${apt[*]}"
    $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${apt[@]}" >/dev/null
  fi
  if [ ! -x .venv/bin/python3 ] || ! .venv/bin/python3 -c "import motmetrics, pymavlink, PIL, onnx, lxml" 2>/dev/null; then
    echo "== python venv for the cross-checks (.venv)"
    python3 -m venv .venv
    .venv/bin/python3 -m pip install -q --disable-pip-version-check -r scripts/requirements-test.txt
  fi
  # shellcheck source=scripts/lib/fts.sh
  source scripts/lib/fts.sh
  fts_venv
}
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
echo "== in the background: chromium, .venv, .venv-tak (log: $work/prepare.log)"
prepare > "$work/prepare.log" 2>&1 &
prepare_pid=$!
export PATH="$PWD/.venv/bin:$PATH"

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
# The loopback tests start a simulator and mgmot each; one test at a time in each lane keeps
# them within their real-time budgets on a 2-core machine.
export RUST_TEST_THREADS=1
# The fuzz targets (fuzz/README.md, tests/fuzz_decoders.rs) run inside the suite on a million
# generated inputs each (about 15 s in all; a separate `cargo test -p mgmot --test main` would
# resolve features for one package and rebuild mgmot). The seed comes from the commit, so each
# commit tries new inputs and a finding is reproducible with the printed seed.
export MGMOT_FUZZ_CASES=1000000
MGMOT_FUZZ_SEED="0x$(git rev-parse --short=15 HEAD 2>/dev/null || echo 6d676d6f7466757a)"
export MGMOT_FUZZ_SEED
export MGMOT_FUZZ_SUMMARY="$work/fuzz_summary"
# Build every test first (the whole workspace: one feature resolution, the demo's build reused).
cargo test --workspace --release --no-run --message-format=json > "$work/build.json"
main_tests="$(python3 - "$work/build.json" "$PWD/tests/main.rs" <<'PY'
import json, sys
for line in open(sys.argv[1]):
    m = json.loads(line) if line.startswith("{") else {}
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["src_path"] == sys.argv[2]:
        print(m["executable"])
PY
)"
[ -x "$main_tests" ] || { echo "test: could not find the tests/main.rs test binary in cargo's build output" >&2; exit 1; }
if ! wait "$prepare_pid"; then
  cat "$work/prepare.log" >&2
  echo "test: installing chromium or the Python venvs (.venv, .venv-tak) failed; its log is above" >&2
  exit 1
fi
cat "$work/prepare.log"
# Two lanes, as the tests mostly wait on real time (a scenario played at 30 frames/s) rather
# than on the CPU: the long flights whose processes use little CPU (`ground::`, two drones for
# 180 s and 90 s with the replay detector, about 16 % of the two cores; `runtime_link::`, one
# drone with the replay detector) run in a second lane beside the rest of the suite, which
# holds the tests that run the real detector in real time. Each lane runs one test at a time.
# The first lane skips the second's tests by their exact names, listed from the binary (a
# plain `--skip ground::` would also skip the unit tests of src/ground/).
lane_areas=(ground:: runtime_link::)
mapfile -t lane_tests < <("$main_tests" --list "${lane_areas[@]}" | sed -n 's/: test$//p')
[ ${#lane_tests[@]} -gt 0 ] || { echo "test: no tests in ${lane_areas[*]}" >&2; exit 1; }
echo "== cargo test (release), in two lanes: ${#lane_tests[@]} tests of tests/main.rs [${lane_areas[*]}] beside the rest (log: $work/lane.log)"
"$main_tests" --exact "${lane_tests[@]}" > "$work/lane.log" 2>&1 &
lane_pid=$!
skips=()
for t in "${lane_tests[@]}"; do skips+=(--skip "$t"); done
rest=0
cargo test --workspace --release -- --exact "${skips[@]}" || rest=$?
lane=0
wait "$lane_pid" || lane=$?
echo "== the second lane (tests/main.rs: ${lane_areas[*]})"
cat "$work/lane.log"
if [ "$rest" -ne 0 ] || [ "$lane" -ne 0 ]; then
  echo "test: cargo test failed (the suite: exit $rest; the second lane: exit $lane)" >&2
  exit 1
fi
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
