#!/usr/bin/env bash
# This build against an earlier commit, side by side in one invocation: per
# scene, the earlier build on that commit's own scene file and this build on
# this one's, on one thread, alternating, REPEAT times each. Prints a table of
# ms/step as median [min, max], the ratio earlier / this per pair of runs,
# each build's contacts over the run (they differ where the contact model
# changed between the commits), its triangle pairs checked per contact, and
# its narrow phase's nanoseconds per triangle pair checked (medians).
# The earlier commit is built in a worktree under out/compare (a first build
# takes about as long as this one's); OLD_TARGET names a target directory
# already holding its release build instead.
# Usage: scripts/compare-builds.sh REV [REPEAT [SCENE:STEPS ...]]
#   e.g. scripts/compare-builds.sh 0653782 3 hopper-400.toml:7000
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
rev=${1:?usage: scripts/compare-builds.sh REV [REPEAT [SCENE:STEPS ...]]}
repeat=${2:-3}
shift $(($# < 2 ? $# : 2))
specs=("$@")
[ ${#specs[@]} -gt 0 ] || specs=(hopper.toml:7000 hopper-400.toml:7000 silo-1000.toml:1500)
git rev-parse --verify --quiet "$rev^{commit}" > /dev/null || { echo "compare-builds: no commit $rev" >&2; exit 2; }
work=out/compare
mkdir -p "$work"
tree=$work/tree-$rev
if [ ! -d "$tree" ]; then
  git worktree add --detach "$tree" "$rev" >&2
fi
old_target=${OLD_TARGET:-$PWD/$work/target-$rev}
if [ -z "${OLD_TARGET:-}" ]; then
  (cd "$tree" && CARGO_TARGET_DIR="$old_target" cargo build --release -p experiments >&2)
fi
cargo build --release -p experiments >&2
old=$old_target/release/tridem
new=$PWD/target/release/tridem
json() { python3 -c "import json,sys; j=json.load(sys.stdin); print($1)"; }
spread() { python3 -c "
import sys, statistics as s
v = sorted(float(x) for x in sys.stdin.read().split())
print('%.3f [%.3f, %.3f]' % (s.median(v), v[0], v[-1]))"; }
med() { python3 -c "
import sys, statistics as s; print('%.0f' % s.median(float(x) for x in sys.stdin.read().split()))"; }
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/compare-builds.sh $rev $repeat ${specs[*]}\` on $cpu ($(nproc) cores), commit $(git rev-parse --short HEAD) against $(git rev-parse --short "$rev"), $(date -u +%Y-%m-%d); one thread, $repeat alternating runs each: median [min, max]."
echo
echo "| scene | steps | $rev (ms/step) | this build (ms/step) | $rev / this | contacts, $rev / this | triangle pairs per contact, $rev / this | narrow phase ns per triangle pair, $rev / this |"
echo "|---|---|---|---|---|---|---|---|"
for spec in "${specs[@]}"; do
  name=${spec%%:*}; steps=${spec##*:}
  declare -A ms=() contacts=() per_contact=() ns_pair=()
  for k in $(seq "$repeat"); do
    for build in old new; do
      if [ $build = old ]; then bin=$old; scene=$tree/scenes/$name; else bin=$new; scene=scenes/$name; fi
      j=$("$bin" run "$scene" --steps "$steps" --threads 1 --json --quiet --output "$work/run-$build" --overwrite 2>/dev/null)
      ms[$build]+="$(echo "$j" | json '1e3*j["seconds"]/j["steps"]') "
      contacts[$build]=$(echo "$j" | json 'j["contacts"]')
      per_contact[$build]=$(echo "$j" | json '"%.1f" % (j["triangle_pairs_checked"] / max(j["contacts"], 1))')
      ns_pair[$build]+="$(echo "$j" | json '1e9*j["section_seconds"]["narrow_phase"]/max(j["triangle_pairs_checked"], 1)') "
    done
  done
  o=(${ms[old]}); n=(${ms[new]})
  ratios=$(for k in $(seq 0 $((repeat - 1))); do python3 -c "print(${o[$k]}/${n[$k]})"; done)
  ns=$(for build in old new; do echo ${ns_pair[$build]} | med; done | paste -sd/ | sed 's|/| / |')
  echo "| $name | $steps | $(echo ${ms[old]} | spread) | $(echo ${ms[new]} | spread) | $(echo $ratios | spread) | ${contacts[old]} / ${contacts[new]} | ${per_contact[old]} / ${per_contact[new]} | $ns |"
  unset ms contacts per_contact ns_pair
done
