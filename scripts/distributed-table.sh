#!/usr/bin/env bash
# One rank x CORES threads against CORES ranks x 1 thread, side by side in
# one invocation (a table of docs/tables.md, written by scripts/tables.sh):
# per scene, the runs alternate, each REPEAT times, and the medians are
# compared. CORES defaults to the machine's.
# Usage: scripts/distributed-table.sh [REPEAT [CORES]]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
repeat=${1:-3}
cores=${2:-$(nproc)}
cargo build --release -p experiments >&2
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
tridem=target/release/tridem
field() { grep -o "\"$1\":[-0-9.e+]*" | head -1 | cut -d: -f2; }
# The mean over ranks of one entry of the per-step table.
mean_of() { grep -o "\"$1\":{[^}]*}" | grep -o '"mean":[-0-9.e+]*' | cut -d: -f2; }
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/distributed-table.sh $repeat $cores\` on $cpu ($(nproc) cores), commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d); medians of $repeat alternating runs."
echo
echo "| scene | steps | 1 rank x $cores threads (ms/step) | $cores ranks x 1 thread (ms/step) | ratio | wait (ms/step, mean over ranks) | ghosts per rank | busy imbalance |"
echo "|---|---|---|---|---|---|---|---|"
for spec in hopper.toml:7000 hopper-400.toml:2000 silo.toml:1000; do
  scene=scenes/${spec%%:*}; steps=${spec##*:}
  one=(); two=(); wait=(); ghosts=(); imb=()
  for _ in $(seq "$repeat"); do
    j=$($tridem run "$scene" --steps "$steps" --threads "$cores" --json --quiet 2>/dev/null)
    one+=("$(echo "$j" | field seconds)")
    j=$(mpirun --oversubscribe -np "$cores" $tridem run "$scene" --steps "$steps" --threads 1 --json --quiet 2>/dev/null)
    two+=("$(echo "$j" | field seconds)")
    wait+=("$(echo "$j" | mean_of wait_seconds)")
    ghosts+=("$(echo "$j" | mean_of ghosts_received)")
    imb+=("$(echo "$j" | field busy_imbalance)")
  done
  o=$(printf '%s\n' "${one[@]}" | median); t=$(printf '%s\n' "${two[@]}" | median)
  w=$(printf '%s\n' "${wait[@]}" | median); g=$(printf '%s\n' "${ghosts[@]}" | median)
  i=$(printf '%s\n' "${imb[@]}" | median)
  awk -v s="${spec%%:*}" -v n="$steps" -v o="$o" -v t="$t" -v w="$w" -v g="$g" -v i="$i" \
    'BEGIN { printf "| %s | %d | %.3f | %.3f | %.2f | %.3f | %.0f | %.2f |\n", s, n, 1e3*o/n, 1e3*t/n, t/o, 1e3*w, g, i }'
done
