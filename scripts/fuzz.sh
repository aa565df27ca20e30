#!/usr/bin/env bash
# Runs every cargo-fuzz target of fuzz/ (libFuzzer) for SECONDS_PER_TARGET seconds each
# (default 60) and prints, per target, the number of inputs it ran and any finding.
#
#   ./scripts/fuzz.sh [SECONDS_PER_TARGET]
#
# Installs cargo-fuzz when missing (cargo install, from crates.io). cargo-fuzz needs a nightly
# compiler; on stable the script sets RUSTC_BOOTSTRAP=1, which lets stable rustc take the
# sanitizer flags. Environment:
#   FUZZ_TARGETS="a b"   only these targets (default: all, `cargo fuzz list`)
#   FUZZ_RUNS=N          stop each target after N inputs (still bounded by the seconds)
#   FUZZ_SANITIZER=S     address (default) or none (faster; safe Rust needs no ASan)
#   FUZZ_TARGET_DIR=DIR  build directory (default fuzz/target)
#   FUZZ_JOBS=N          cargo build jobs
#
# New inputs libFuzzer finds go to fuzz/work/<target>/ (not committed); the committed corpus
# fuzz/corpus/<target>/ is only read, and fuzz/dict/<target>.dict is the target's dictionary.
# A crash is saved under fuzz/artifacts/<target>/, printed in hex with its panic message, and
# the script exits 1. To keep a fixed finding as a regression input, copy it into
# fuzz/corpus/<target>/ (tests/fuzz_decoders.rs replays it in the normal `cargo test`).
# More in fuzz/README.md.
set -euo pipefail
cd "$(dirname "$0")/.."

secs="${1:-60}"
case "$secs" in
'' | *[!0-9]*)
  echo "usage: $0 [SECONDS_PER_TARGET]" >&2
  exit 2
  ;;
esac

if ! command -v cargo-fuzz >/dev/null 2>&1; then
  echo "fuzz: installing cargo-fuzz"
  cargo install cargo-fuzz --locked
fi
command -v c++ >/dev/null 2>&1 || {
  echo "fuzz: a C++ compiler is needed for libFuzzer (apt-get install build-essential)" >&2
  exit 1
}
if ! rustc --version | grep -q nightly; then
  export RUSTC_BOOTSTRAP=1
fi

target_dir="$(realpath -m "${FUZZ_TARGET_DIR:-fuzz/target}")"
sanitizer="${FUZZ_SANITIZER:-address}"
build_args=(--sanitizer "$sanitizer" --target-dir "$target_dir")
[ -n "${FUZZ_JOBS:-}" ] && export CARGO_BUILD_JOBS="$FUZZ_JOBS"

targets="${FUZZ_TARGETS:-$(cargo fuzz list)}"
echo "fuzz: building (sanitizer $sanitizer, $target_dir)"
cargo fuzz build "${build_args[@]}" || {
  echo "fuzz: build failed" >&2
  exit 1
}

mkdir -p fuzz/work fuzz/artifacts
summary=()
failed=0
for t in $targets; do
  log="fuzz/work/$t.log"
  mkdir -p "fuzz/work/$t" "fuzz/artifacts/$t"
  before="$(ls "fuzz/artifacts/$t" | wc -l)"
  libfuzzer_args=(-max_total_time="$secs" -print_final_stats=1 -timeout=10 -rss_limit_mb=4096)
  [ -f "fuzz/dict/$t.dict" ] && libfuzzer_args+=(-dict="$PWD/fuzz/dict/$t.dict")
  [ -n "${FUZZ_RUNS:-}" ] && libfuzzer_args+=(-runs="$FUZZ_RUNS")
  echo "fuzz: $t for ${secs}s${FUZZ_RUNS:+ or $FUZZ_RUNS inputs}"
  start=$(date +%s)
  set +e
  cargo fuzz run "${build_args[@]}" "$t" "$PWD/fuzz/work/$t" "$PWD/fuzz/corpus/$t" -- \
    "${libfuzzer_args[@]}" >"$log" 2>&1
  status=$?
  set -e
  took=$(($(date +%s) - start))
  runs="$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)"
  [ -n "$runs" ] || runs="$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#')"
  after="$(ls "fuzz/artifacts/$t" | wc -l)"
  if [ "$status" -ne 0 ] || [ "$after" -gt "$before" ]; then
    failed=1
    summary+=("$(printf '%-20s %12s inputs %6ss  FINDING (exit %s, log %s)' "$t" "${runs:-?}" "$took" "$status" "$log")")
    echo "fuzz: $t: finding"
    grep -m1 -A3 -E "panicked at|ERROR: (AddressSanitizer|libFuzzer)" "$log" || tail -20 "$log"
    for f in $(ls -t "fuzz/artifacts/$t" | head -n $((after - before > 0 ? after - before : 1))); do
      echo "  input fuzz/artifacts/$t/$f ($(stat -c %s "fuzz/artifacts/$t/$f") bytes):"
      echo "  $(head -c 512 "fuzz/artifacts/$t/$f" | od -An -v -tx1 | tr -d ' \n')"
    done
  else
    summary+=("$(printf '%-20s %12s inputs %6ss  ok' "$t" "${runs:-?}" "$took")")
  fi
done

echo
echo "fuzz summary (${secs}s per target${FUZZ_RUNS:+, at most $FUZZ_RUNS inputs}):"
printf '  %s\n' "${summary[@]}"
exit "$failed"
