#!/usr/bin/env bash
# Bytes per output step of a scene's run.h5 (default the hopper's): the file
# after nine output steps less the file after one, over eight; with every
# field (the default), with the states and energy books alone, and with
# each of the scene's `[output] fields` alone (docs/output.md).
# Usage: scripts/output-size.sh [SCENE]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
cargo build --release -p experiments >&2
tridem=${TRIDEM:-target/release/tridem}
scene=${1:-scenes/hopper.toml}
every=$(grep -m1 '^output_every' "$scene" | tr -dc 0-9)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "$scene, bytes of run.h5 per output step (nine output steps less one, over eight):"
echo
echo "| output.fields | bytes per output step |"
echo "|---|---|"
for fields in '["surface", "particles", "contacts"]' '[]' '["surface"]' '["particles"]' '["contacts"]'; do
  rm -rf "$work/one" "$work/nine"
  $tridem run "$scene" --output "$work/one" --steps 0 --quiet --set "output.fields=$fields" >/dev/null
  $tridem run "$scene" --output "$work/nine" --steps $((8 * every)) --quiet --set "output.fields=$fields" >/dev/null
  one=$(stat -c %s "$work/one/run.h5")
  nine=$(stat -c %s "$work/nine/run.h5")
  echo "| \`$fields\` | $(( (nine - one) / 8 )) |"
done
