#!/usr/bin/env bash
# Bytes per output step of the hopper's run.h5: the file after nine output
# steps less the file after one, over eight.
# Usage: scripts/output-size.sh [SCENE]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
cargo build --release -p experiments >&2
scene=${1:-scenes/hopper.toml}
every=$(grep -m1 '^output_every' "$scene" | tr -dc 0-9)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
target/release/tridem run "$scene" --output "$work/one" --steps 0 --quiet >/dev/null
target/release/tridem run "$scene" --output "$work/nine" --steps $((8 * every)) --quiet >/dev/null
one=$(stat -c %s "$work/one/run.h5")
nine=$(stat -c %s "$work/nine/run.h5")
echo "$scene: $one bytes with one output step, $nine with nine: $(( (nine - one) / 8 )) bytes per output step"
