#!/usr/bin/env bash
# Runs every study at its default size and regenerates docs/results.md with
# its figures (docs/figures/study-*), each with the command that made it,
# the machine and the commit.
# Usage: scripts/reproduce.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/measure-env.sh
figs=docs/figures
mkdir -p "$figs"
page=docs/results.md.new
{
  echo "# Results"
  echo
  echo "Every figure below is made by \`scripts/reproduce.sh\`, which runs each study at its"
  echo "default size (docs/distributed.md explains the runs and their metrics). Measured on $stamp."
  echo
} > "$page"
study() {
  local name=$1 about=$2; shift 2
  local cmd="tridem study $name $*"
  $tridem study "$name" --output "out/study-$name" --overwrite "$@" > "out/study-$name.txt"
  for f in out/study-"$name"/*.svg out/study-"$name"/*.png; do cp "$f" "$figs/study-$name-$(basename "$f")"; done
  {
    echo "## $name"
    echo
    echo "\`$cmd\`"
    echo
    echo "$about"
    echo
    for f in out/study-"$name"/*.svg; do echo "![$name: $(basename "$f" .svg)](figures/study-$name-$(basename "$f"))"; echo; done
    echo '```'
    cat "out/study-$name.txt"
    echo '```'
    echo
  } >> "$page"
}
mkdir -p out
study repartition-frequency "Repartitioning every K steps (never: at the start only) on the \
1,000-particle silo: per-step time of each section against K, and the imbalance of the ranks' busy time \
over the run (particles keep their rank between repartitionings, so their count stays balanced while their work does not). The cost model amortises one repartitioning over K steps and charges the measured \
imbalance at a fitted rate; its recommendation is printed below the table with the measured best."
study partitioners "The five partitioners on the same run, repartitioning every 20 steps: \
imbalance of the ranks' busy time and time per step over the run. Partition and migration seconds, and \
ghosts per rank, are in the table."
study exchange "Blocking against non-blocking ghost exchange on 2, 3 and 4 ranks: the time \
each rank waits for its ghosts after (non-blocking) or before (blocking) the detection among its \
own bodies, and the step time. On a machine with fewer cores than ranks, ranks share cores \
(oversubscribed) and the waits measure that sharing as much as the network." --ranks 2,3,4
study scheduling "Static, dynamic and guided sharing of the body pairs among threads, with the \
hybrid kernel falling back on whole batches (the published kernel) or on the failed pairs only, at 1 \
to all cores: time per step, the share of the narrow phase's thread time spent idle, and the spread of \
the fallback rate between the most and the least falling-back task. The last column of the table says \
whether the final state is bit for bit the one-thread static run's: the fallback rate per task moves \
with the schedule, the answers do not, since both branches of the hybrid return the exact distance."
study accuracy "Each kernel setting's time per step against the root mean square distance of \
the particles' final positions from a brute-force run. The run brute-dt+1e-14 changes only the time \
step, by 1e-14: its deviation is what rounding alone grows into over the run (granular flow is \
chaotic), the floor under which a kernel's error cannot be told from chaos. Settings on the bottom \
line give brute force's trajectories bit for bit."
mv "$page" docs/results.md
echo "docs/results.md regenerated" >&2
