#!/usr/bin/env bash
# Culling by the bodies' hulls (the default) against culling by boxes alone,
# side by side in one invocation (docs/tables.md, "Contact culling", written
# by scripts/tables.sh; docs/dem.md, "Culling"). Per scene, the same run on
# one thread with `contact.culling = "hulls"` and `"boxes"`, alternating,
# REPEAT times each: ms/step as median [min, max], the ratio boxes / hulls
# per pair of runs, the triangle pairs checked per contact under each, the
# share of listed body pairs the hulls settle (and of those left out
# unexamined, still apart since an earlier showing), the share examined on
# the triangle pairs kept at an earlier culling, and whether the two final
# checkpoints are the same bits.
# The boulders fall for a while before they touch: their rows resume, for
# BOULDER_STEPS, from a pile this script makes first (out/culling/pile).
# Usage: scripts/culling-table.sh [REPEAT [BOULDER_STEPS]]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
repeat=${1:-3}
boulder_steps=${2:-100}
cargo build --release -p experiments >&2
tridem=$PWD/target/release/tridem
work=out/culling
rm -rf "$work"
mkdir -p "$work"
json() { python3 -c "import json,sys; j=json.load(sys.stdin); print($1)"; }
# median and [min, max] of the numbers on stdin
spread() { python3 -c "
import sys, statistics as s
v = sorted(float(x) for x in sys.stdin.read().split())
print('%.3f [%.3f, %.3f]' % (s.median(v), v[0], v[-1]))"; }
med() { python3 -c "
import sys, statistics as s; print('%.1f' % s.median(float(x) for x in sys.stdin.read().split()))"; }
# the scene's contact table with `culling` set, for --set
contact_with() { python3 -c "
import tomllib, sys
c = tomllib.load(open('$1', 'rb'))['effects']['contact']
c['culling'] = '$2'
print('effects.contact={ ' + ', '.join('%s = %r' % (k, v) for k, v in c.items()).replace(\"'\", '\"') + ' }')"; }

echo "making the boulders' pile (4,000 steps on $(nproc) threads)" >&2
$tridem run scenes/boulders.toml --steps 4000 --quiet --output "$work/pile" >&2

cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/culling-table.sh $repeat $boulder_steps\` on $cpu ($(nproc) cores), commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d); one thread, $repeat alternating runs each: median [min, max]."
echo
echo "| scene | steps | hulls (ms/step) | boxes (ms/step) | boxes / hulls | triangle pairs per contact, hulls / boxes | body pairs settled by hulls | left out as still apart | on kept triangle pairs | same bits |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for spec in hopper.toml:7000 hopper-400.toml:7000 silo-1000.toml:1500 boulders.toml:$boulder_steps; do
  name=${spec%%:*}; scene=scenes/$name; steps=${spec##*:}
  declare -A secs=() per=() settled=() still=() kept=()
  for k in $(seq "$repeat"); do
    for culling in hulls boxes; do
      out=$work/$name-$culling-$k
      args=(run "$scene" --steps "$steps" --threads 1 --json --quiet --output "$out"
        --set "$(contact_with "$scene" $culling)")
      if [ "$name" = boulders.toml ]; then
        mkdir -p "$out"
        cp "$work/pile/checkpoint.h5" "$out/"
        args+=(--resume "$out/checkpoint.h5")
      fi
      j=$($tridem "${args[@]}" 2>/dev/null)
      secs[$culling]+="$(echo "$j" | json '1e3*j["seconds"]/j["steps"]') "
      per[$culling]+="$(echo "$j" | json 'j["triangle_pairs_per_contact"]') "
      # listed body pairs settled by hulls: shown apart now, or still apart
      # from an earlier showing (left out unexamined)
      settled[$culling]+="$(echo "$j" | json '(j["body_pairs_apart_by_hulls"] + j["body_pairs_known_apart"])/max(1, j["body_pairs_checked"] + j["body_pairs_known_apart"])') "
      still[$culling]+="$(echo "$j" | json 'j["body_pairs_known_apart"]/max(1, j["body_pairs_checked"] + j["body_pairs_known_apart"])') "
      kept[$culling]+="$(echo "$j" | json 'j["body_pairs_near_kept"]/max(1, j["body_pairs_checked"] + j["body_pairs_known_apart"])') "
    done
  done
  h=(${secs[hulls]}); b=(${secs[boxes]})
  ratios=$(for k in $(seq 0 $((repeat - 1))); do python3 -c "print(${b[$k]}/${h[$k]})"; done)
  same=yes
  for k in $(seq "$repeat"); do
    cmp -s "$work/$name-hulls-$k/checkpoint.h5" "$work/$name-boxes-$k/checkpoint.h5" || same=no
  done
  percent() { python3 -c "
import sys, statistics as s; print('%.1f%%' % (100 * s.median(float(x) for x in sys.stdin.read().split())))"; }
  share=$(echo ${settled[hulls]} | percent)
  left=$(echo ${still[hulls]} | percent)
  on_kept=$(echo ${kept[hulls]} | percent)
  echo "| $name | $steps | $(echo ${secs[hulls]} | spread) | $(echo ${secs[boxes]} | spread) | $(echo $ratios | spread) | $(echo ${per[hulls]} | med) / $(echo ${per[boxes]} | med) | $share | $left | $on_kept | $same |"
  unset secs per settled still kept
done
rm -rf "$work"
