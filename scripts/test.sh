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

echo "== cargo fmt --check"
cargo fmt --all --check
echo "== cargo clippy"
cargo clippy --workspace --all-targets --quiet -- -D warnings
echo "== cargo test"
cargo test --workspace
