#!/usr/bin/env bash
# Measures every partitioner on every workload (the table in docs/partition.md).
# Usage: scripts/partition-table.sh [ITEMS] [RANKS] [OUTDIR]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
items=${1:-1000000}
ranks=${2:-2}
out=${3:-out/partition}
cargo build --release -p experiments >&2
mkdir -p "$out"
for w in uniform blobs hopper; do
  for p in zoltan-rcb zoltan-rib zoltan-hsfc metis rcb; do
    mpirun --oversubscribe -np "$ranks" target/release/tridem partition --partitioner "$p" \
      --workload "$w" --items "$items" --steps 3 --every 1 --json --output "$out"
  done
done
