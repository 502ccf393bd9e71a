#!/usr/bin/env bash
# The main job: installs what is missing, builds in release mode, checks the MPI stack
# on 2 ranks (tridem info), then runs the hopper scene with HDF5 + XDMF output, and
# draws its last step (render.png) and its energy books (energy.svg, .png, .csv).
# Usage: scripts/main-job.sh [OUTPUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
scripts/install-deps.sh
cargo build --release -p experiments
out=${1:-out/hopper}
echo "main-job: mpirun -np 2 target/release/tridem info"
mpirun --oversubscribe -np 2 target/release/tridem info
echo "main-job: target/release/tridem run scenes/hopper.toml --output $out --overwrite"
# --overwrite: the main job reproduces the hopper, replacing an earlier run's output.
target/release/tridem run scenes/hopper.toml --output "$out" --overwrite
echo "main-job: target/release/tridem render $out --contacts --output $out/render.png"
target/release/tridem render "$out" --contacts --output "$out/render.png"
echo "main-job: target/release/tridem plot $out --energy"
target/release/tridem plot "$out" --energy
