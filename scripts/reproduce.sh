#!/usr/bin/env bash
# Runs every study at its default size and regenerates docs/results.md with
# its figures (docs/figures/study-*), each with the command that made it,
# the machine and the commit; then docs/tables.md (scripts/tables.sh), so
# that both pages are made at one commit by one command.
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
  echo "default size (docs/distributed.md explains the runs and their metrics) and regenerates"
  echo "[tables.md](tables.md) with it. Measured on $stamp. Each setting runs five times, the"
  echo "settings in turn; tables give the median [least, most], figures error bars. Each timing"
  echo "study runs its first setting twice under two labels: their difference is its noise floor,"
  echo "and the line \"found:\" under each table says which settings differ by more than it."
  echo
} > "$page"
# study NAME ABOUT [ARGS...]: a study on its default scene, or, when ARGS
# start with --scene FILE, on that scene, its section and files named after it.
study() {
  local name=$1 about=$2; shift 2
  local key=$name title=$name
  if [ "${1:-}" = --scene ]; then
    key="$name-$(basename "$2" .toml)"
    title="$name on $(basename "$2")"
  fi
  local cmd="tridem study $name $*"
  $tridem study "$name" --output "out/study-$key" --overwrite "$@" > "out/study-$key.txt"
  for f in out/study-"$key"/*.svg out/study-"$key"/*.png; do cp "$f" "$figs/study-$key-$(basename "$f")"; done
  {
    echo "## $title"
    echo
    echo "\`$cmd\`"
    echo
    echo "$about"
    echo
    for f in out/study-"$key"/*.svg; do echo "![$title: $(basename "$f" .svg)](figures/study-$key-$(basename "$f"))"; echo; done
    echo '```'
    cat "out/study-$key.txt"
    echo '```'
    echo
  } >> "$page"
}
mkdir -p out
study repartition-frequency "Repartitioning every K steps (never: at the start only), and \
when the ranks' busy time over 20 steps is imbalanced beyond τ, on the column collapse \
(scenes/collapse.toml: a block of grains released against one wall, whose ranks' work parts as it \
spreads): time per step, the busy imbalance and the particles migrated per setting; time by section \
against K; the imbalance over the run. The cost model is fitted to the two extremes (every step, \
never) and predicts the settings between; the line under the table says whether it picked the \
measured best within the noise floor."
study repartition-frequency "The same study on the off-centre silo (scenes/silo-offset.toml: a \
charge falling into its left side while the bed over the slot on the right drains; an equal split \
gives one rank the charge in flight, the other the draining bed)." --scene scenes/silo-offset.toml
study repartition-frequency "The same study on mixed sizes (scenes/mixed.toml: 20 particles of \
2,000 triangles falling onto the left part of a bed of 2,000 grains; the first partition weighs \
triangles, so one rank holds the large particles and the other most of the grains, whose contacts \
are the work)." --scene scenes/mixed.toml
study partitioners "The five partitioners on the column collapse, repartitioning every 20 steps: \
time per step, busy imbalance and migration per partitioner, and the imbalance over the run."
study exchange "Blocking against non-blocking ghost exchange on 2, 3 and 4 ranks of the \
1,000-particle silo: the wait (the time inside the call that completes the exchange, the same \
measure in both modes) and the step time. On a machine with fewer cores than ranks, ranks share \
cores (oversubscribed) and the waits measure that sharing as much as the network." --ranks 2,3,4
study scheduling "Static, dynamic and guided sharing of the body pairs among threads, with the \
hybrid kernel falling back on whole batches (the published kernel) or on the failed pairs only, at 1 \
to all cores: time per step, the share of the narrow phase's thread time spent idle, and the spread of \
the fallback rate between the most and the least falling-back task. The last column of the table says \
whether the final state is bit for bit the one-thread static run's: the fallback rate per task moves \
with the schedule, the answers do not, since both branches of the hybrid return the exact distance."
study accuracy "Each kernel setting's time per step against the root mean square distance of \
the particles' final positions from a brute-force run, over 500 steps of the 1,000-particle silo's \
dense phase: every run resumes from the state brute force reaches in 5,000 steps, when the grains \
have landed. The table adds the contacts per step, the energy books' drift over the largest kinetic \
energy, and the contacts deeper than the halos. The run brute-g+1e-14 scales gravity by 1 + 1e-14: \
its deviation is what rounding alone grows into over the run (granular flow is chaotic), the floor \
under which a kernel's error cannot be told from chaos. Settings on the bottom line give brute \
force's trajectories bit for bit." --repeat 3
mv "$page" docs/results.md
echo "docs/results.md regenerated" >&2
scripts/tables.sh
