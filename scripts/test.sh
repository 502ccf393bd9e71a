#!/usr/bin/env bash
# Every check CI makes: formatting, clippy with warnings as errors, the API docs
# without broken links, and all tests
# (multi-rank ones included: they start mpirun themselves). Installs what is missing first.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
scripts/install-deps.sh --render
rustup component add rustfmt clippy >/dev/null 2>&1 || true
echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy"
# The dev profile, as cargo doc's: the two share the dependencies' checked
# metadata and build scripts instead of making them twice.
cargo clippy --workspace --all-targets -- -D warnings
echo "== cargo doc"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet
echo "== cargo test"
cargo test --workspace --release
echo "== SLURM job templates on a local single-node SLURM"
if [ "$(id -u)" -eq 0 ]; then
  scripts/test-slurm.sh
else
  echo "skipped: starting slurmctld and slurmd needs root (scripts/test-slurm.sh)"
fi
