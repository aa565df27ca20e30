# shellcheck shell=bash
# The SITL benches' tools (sourced by scripts/bench_sitl.sh and scripts/bench_sitl_fleet.sh),
# run from the repository root. Sets the globals `bin_dir` and `python` in place.

# `bin_dir`: DIR/mgmot and DIR/mgmot-sim as given (checked), or, when empty, built here with
# cargo into target/release.
bench_binaries() {
  if [ -n "$bin_dir" ]; then
    bin_dir=$(cd "$bin_dir" && pwd)
    for b in mgmot mgmot-sim; do
      if [ ! -x "$bin_dir/$b" ]; then echo "bench: $bin_dir/$b not found" >&2; exit 2; fi
    done
  else
    bash scripts/setup.sh >/dev/null
    cargo build --release -q -p mgmot -p mgmot-sim
    bin_dir=$PWD/target/release
  fi
}

# `python`: a Python with pymavlink as given (checked), or, when empty, .venv (created with
# scripts/requirements-test.txt when it lacks pymavlink).
bench_python() {
  if [ -z "$python" ]; then
    if [ ! -x .venv/bin/python3 ] || ! .venv/bin/python3 -c "import pymavlink" 2>/dev/null; then
      python3 -m venv .venv && .venv/bin/python3 -m pip install -q -r scripts/requirements-test.txt
    fi
    python=$PWD/.venv/bin/python3
  elif ! "$python" -c "import pymavlink" 2>/dev/null; then
    echo "bench: $python has no pymavlink" >&2
    exit 2
  fi
}
