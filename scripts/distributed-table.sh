#!/usr/bin/env bash
# The DEM across ranks, measured side by side in one invocation (the
# tables of docs/tables.md, "DEM across ranks", written by scripts/tables.sh):
#  1. per scene, 1 rank x 1 thread, 1 rank x CORES threads and CORES ranks x
#     1 thread, alternating, REPEAT times each: medians and min-max of
#     ms/step, the ratio of ranks to threads, the parallel efficiency
#     T(1x1) / (CORES T(CORES x 1)); and the machine's ceiling on that
#     efficiency: CORES independent 1 x 1 runs at once, one per core, share
#     the caches, memory and clock of the cores, so T(1x1) / T(the slowest
#     copy) is the most any split of the work into CORES ranks can reach;
#     the busy imbalance of the ranks' totals, and step by step (the slowest
#     rank's busy time summed over the steps, over the mean rank's: what the
#     waits for the slowest rank cost, each step), and the same of the cost
#     model's work (a count, whatever the cores' speeds: the part of those
#     waits that the split of the work causes);
#     silo-1000 twice: its first 1,500 steps (the filling, few contacts, short
#     steps) and its first 3,000 (into the packed bed);
#  2. the exchange: the wait with a blocking and a non-blocking exchange on
#     silo-1000, alternating;
#  3. memory: peak resident memory per rank of silo on 1, 2 and 4 ranks, less
#     that of two-particles under the same launcher (the data part), and
#     silo-50k on 2 ranks.
# Usage: scripts/distributed-table.sh [REPEAT [CORES]]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
repeat=${1:-5}
cores=${2:-$(nproc)}
cargo build --release -p experiments >&2
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
tridem=target/release/tridem
mpi() { mpirun --oversubscribe -np "$1" "${@:2}"; }
json() { python3 -c "import json,sys; j=json.load(sys.stdin); print($1)"; }
# median and [min, max] of the numbers on stdin
spread() { python3 -c "
import sys, statistics as s
v = sorted(float(x) for x in sys.stdin.read().split())
print('%.3f [%.3f, %.3f]' % (s.median(v), v[0], v[-1]))"; }
med() { python3 -c "
import sys, statistics as s; print(s.median(float(x) for x in sys.stdin.read().split()))"; }
# seconds of the slowest of CORES copies of the 1 x 1 run of SCENE for
# STEPS, started together, copy k pinned to core k as mpirun binds rank k
at_once() {
  local dir k
  dir=$(mktemp -d)
  for k in $(seq 0 $((cores - 1))); do
    taskset -c "$((k % $(nproc)))" $tridem run "$1" --steps "$2" --threads 1 --json --quiet 2>/dev/null >"$dir/$k" &
  done
  wait
  cat "$dir"/* | python3 -c "import json,sys; print(max(json.loads(l)['seconds'] for l in sys.stdin))"
  rm -rf "$dir"
}
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/distributed-table.sh $repeat $cores\` on $cpu ($(nproc) cores), commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d); $repeat alternating runs each: median [min, max]."
echo
echo "| scene | steps | 1 x 1 (ms/step) | 1 x $cores threads | $cores ranks x 1 | ranks / threads | efficiency | ceiling ($cores copies at once) | efficiency / ceiling | busy imbalance | busy imbalance, step by step | work imbalance, step by step | ghosts per rank |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for spec in hopper.toml:7000 hopper-400.toml:7000 silo-1000.toml:1500 silo-1000.toml:3000 silo.toml:1000; do
  scene=scenes/${spec%%:*}; steps=${spec##*:}
  one=(); threads=(); ranks=(); copies=(); imb=(); steps_imb=(); work_imb=(); ghosts=()
  for _ in $(seq "$repeat"); do
    one+=("$($tridem run "$scene" --steps "$steps" --threads 1 --json --quiet 2>/dev/null | json 'j["seconds"]')")
    threads+=("$($tridem run "$scene" --steps "$steps" --threads "$cores" --json --quiet 2>/dev/null | json 'j["seconds"]')")
    j=$(mpi "$cores" $tridem run "$scene" --steps "$steps" --threads 1 --json --quiet 2>/dev/null)
    ranks+=("$(echo "$j" | json 'j["seconds"]')")
    imb+=("$(echo "$j" | json 'j["busy_imbalance"]')")
    steps_imb+=("$(echo "$j" | json 'j["busy_imbalance_per_step"]')")
    work_imb+=("$(echo "$j" | json 'j["work_imbalance_per_step"]')")
    ghosts+=("$(echo "$j" | json 'j["per_step_over_ranks"]["ghosts_received"]["mean"]')")
    copies+=("$(at_once "$scene" "$steps")")
  done
  ms() { for x in "$@"; do python3 -c "print(1e3*$x/$steps)"; done; }
  ratios=(); effs=(); ceilings=(); of=()
  for k in $(seq 0 $((repeat - 1))); do
    ratios+=("$(python3 -c "print(${ranks[$k]}/${threads[$k]})")")
    effs+=("$(python3 -c "print(${one[$k]}/($cores*${ranks[$k]}))")")
    ceilings+=("$(python3 -c "print(${one[$k]}/${copies[$k]})")")
    of+=("$(python3 -c "print(${copies[$k]}/($cores*${ranks[$k]}))")")
  done
  echo "| ${spec%%:*} | $steps | $(ms "${one[@]}" | spread) | $(ms "${threads[@]}" | spread) | $(ms "${ranks[@]}" | spread) | $(printf '%s\n' "${ratios[@]}" | spread) | $(printf '%s\n' "${effs[@]}" | spread) | $(printf '%s\n' "${ceilings[@]}" | spread) | $(printf '%s\n' "${of[@]}" | spread) | $(printf '%s\n' "${imb[@]}" | med | xargs printf '%.3f') | $(printf '%s\n' "${steps_imb[@]}" | med | xargs printf '%.3f') | $(printf '%s\n' "${work_imb[@]}" | med | xargs printf '%.3f') | $(printf '%s\n' "${ghosts[@]}" | med | xargs printf '%.0f') |"
done
echo
echo "Exchange on silo-1000 (1,500 steps, $cores ranks): the wait is the time inside the call that completes the ghost exchange, the same measure in both modes."
echo
echo "| exchange | wait (us/step) | step (ms/step) |"
echo "|---|---|---|"
declare -A wait step
for _ in $(seq "$repeat"); do
  for x in blocking nonblocking; do
    j=$(mpi "$cores" $tridem run scenes/silo-1000.toml --steps 1500 --threads 1 --exchange $x --json --quiet 2>/dev/null)
    wait[$x]+="$(echo "$j" | json '1e6*j["per_step_over_ranks"]["wait_seconds"]["mean"]') "
    step[$x]+="$(echo "$j" | json '1e3*j["seconds"]/j["steps"]') "
  done
done
for x in blocking nonblocking; do
  echo "| $x | $(echo ${wait[$x]} | spread) | $(echo ${step[$x]} | spread) |"
done
echo
echo "Memory: peak resident memory per rank (the largest rank's), and its data part: less that of scenes/two-particles.toml under the same launcher (one process alone, the ranks under mpirun)."
echo
echo "| scene | ranks | steps | peak (MiB) | two-particles (MiB) | data part (MiB) | of one rank's | ms/step |"
echo "|---|---|---|---|---|---|---|---|"
peak() { # peak RSS in MiB of `tridem run SCENE --steps N` on P ranks (1: alone)
  if [ "$1" = 1 ]; then
    /usr/bin/time -f '%M' $tridem run "$2" --steps "$3" --threads 1 --quiet --json 2>&1 >/dev/null | tail -1 | xargs -I{} python3 -c "print({}/1024)"
  else
    mpi "$1" $tridem run "$2" --steps "$3" --threads 1 --quiet --json 2>/dev/null | json 'j["peak_rss_bytes"]["max"]/2**20'
  fi
}
base1=""
for spec in silo.toml:1:200 silo.toml:2:200 silo.toml:4:200 silo-50k.toml:2:200; do
  IFS=: read -r name p steps <<<"$spec"
  total=$(peak "$p" "scenes/$name" "$steps")
  base=$(peak "$p" scenes/two-particles.toml 10)
  data=$(python3 -c "print($total-$base)")
  [ "$name" = silo.toml ] && [ "$p" = 1 ] && base1=$data
  of=$([ "$name" = silo.toml ] && python3 -c "print('%.2f' % ($data/$base1))" || echo "-")
  ms=$(if [ "$p" = 1 ]; then $tridem run "scenes/$name" --steps "$steps" --threads 1 --quiet --json 2>/dev/null; else mpi "$p" $tridem run "scenes/$name" --steps "$steps" --threads 1 --quiet --json 2>/dev/null; fi | json '1e3*j["seconds"]/j["steps"]')
  printf '| %s | %s | %s | %.1f | %.1f | %.1f | %s | %.2f |\n' "$name" "$p" "$steps" "$total" "$base" "$data" "$of" "$ms"
done
