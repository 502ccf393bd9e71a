#!/usr/bin/env bash
# The main job: installs what is missing, builds in release mode, runs on 2 MPI ranks.
# Usage: scripts/main-job.sh [RANKS]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
scripts/install-deps.sh
cargo build --release -p experiments
ranks=${1:-2}
echo "main-job: mpirun -np $ranks target/release/tridem info"
mpirun --oversubscribe -np "$ranks" target/release/tridem info
