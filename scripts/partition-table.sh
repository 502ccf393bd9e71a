#!/usr/bin/env bash
# Every partitioner on every workload: three partitioning steps each under
# mpirun. Writes OUTDIR/runs.jsonl (one JSON line per step) and
# OUTDIR/partition.svg (its figure), and prints the markdown table of
# docs/tables.md, stamped with the command, CPU, cores and commit.
# Usage: scripts/partition-table.sh [ITEMS] [RANKS] [OUTDIR]
set -euo pipefail
cd "$(dirname "$0")/.."
items=${1:-1000000}
ranks=${2:-2}
out=${3:-out/partition}
source scripts/measure-env.sh
mkdir -p "$out"
runs=$out/runs.jsonl
: > "$runs.new"
for w in uniform blobs hopper; do
  for p in $("$tridem" partition --list); do
    mpirun --oversubscribe -np "$ranks" "$tridem" partition --partitioner "$p" \
      --workload "$w" --items "$items" --steps 3 --every 1 --json >> "$runs.new"
    echo "partition-table: $w $p done" >&2
  done
done
mv "$runs.new" "$runs"
"$tridem" partition-plot "$runs" --output "$out/partition.svg" >&2
echo "Measured by \`scripts/partition-table.sh $items $ranks\` on $stamp."
echo
echo "| workload | partitioner | step | imbalance | partition s | migrate s | migrated items | migrated MB | ghost items | ghost MB | neighbours | box queries/s |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
awk '
  # The value of key k in this JSON line (a number or a plain string).
  function f(k,   m) {
    if (!match($0, "\"" k "\":\"?[^,\"}]*")) return ""
    m = substr($0, RSTART, RLENGTH)
    sub(/^"[^"]*":"?/, "", m)
    return m
  }
  {
    printf "| %s | %s | %d | %.4f | %.3f | %.3f | %d | %.1f | %d | %.2f | %d | %.1fM |\n",
      f("workload"), f("partitioner"), f("step"), f("imbalance"), f("partition_s"),
      f("migrate_s"), f("migrated_items"), f("migrated_bytes") / 1e6, f("ghost_items"),
      f("ghost_bytes") / 1e6, f("neighbours_max"), f("box_queries_per_s") / 1e6
  }' "$runs"
echo
echo "The ghost exchange alone, a stand-in for the owned contact phase alone (the owned items'"
echo "pairs whose inflated boxes overlap), and the two overlapped, on the uniform workload:"
echo "medians over the three steps, on the slowest rank, from the same records."
echo
echo "| partitioner | ghost items | exchange alone s | owned pairs alone s | overlapped s | sum of the two s | exchange / owned pairs |"
echo "|---|---|---|---|---|---|---|"
python3 - "$runs" <<'PY'
import json, statistics, sys
rows = {}
for line in open(sys.argv[1]):
    r = json.loads(line)
    if r["workload"] == "uniform":
        rows.setdefault(r["partitioner"], []).append(r)
for p, rs in rows.items():
    m = lambda k: statistics.median(r[k] for r in rs)
    ex, own, both = m("ghost_exchange_s"), m("owned_pairs_s"), m("overlapped_s")
    print(f"| {p} | {int(m('ghost_items')):,} | {ex:.4f} | {own:.3f} | {both:.3f} | {ex + own:.3f} | {ex / own:.3f} |")
PY
