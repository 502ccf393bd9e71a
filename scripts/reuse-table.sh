#!/usr/bin/env bash
# What building on the previous partition saves, on the scenes whose ranks'
# work drifts apart (the column collapse, the off-centre silo, mixed sizes),
# on 2 and 4 ranks, repartitioned every 100 steps with each partitioner, once reusing
# the previous partition (the default: RCB keeps its cut axes and starts
# from its old cuts, parts are renumbered to overlap the old owners) and once
# from scratch (--fresh-partitions). Trajectories do not depend on the
# partition, so both runs see the same particles at every repartitioning:
# the difference is the partitioner's alone. Counts, not times
# (oversubscription does not change them). Prints a markdown table.
# Usage: scripts/reuse-table.sh [STEPS]
# (SCENES and PARTITIONERS, space-separated, narrow it down.)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
steps=${1:-3000}
cargo build --release -p experiments >&2
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
tridem=target/release/tridem
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scenes=${SCENES:-collapse silo-offset mixed}
for scene in $scenes; do
  for ranks in 2 4; do
    for p in ${PARTITIONERS:-$($tridem partition --list)}; do
      for mode in reuse fresh; do
        flag=""
        [ "$mode" = fresh ] && flag=--fresh-partitions
        mpirun --oversubscribe -np "$ranks" $tridem run "scenes/$scene.toml" --steps "$steps" \
          --partitioner "$p" --repartition-every 100 --weights pairs $flag --quiet --json \
          --metrics "$tmp/$scene@$p-$ranks-$mode.jsonl" --metrics-every 100 >/dev/null 2>&1
      done
    done
  done
done
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/reuse-table.sh $steps\` on $cpu ($(nproc) cores), commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d)."
echo
python3 - "$tmp" $scenes <<'PY'
import json, sys, glob, os
tmp, scenes = sys.argv[1], sys.argv[2:]
def load(name):
    return [json.loads(l) for l in open(os.path.join(tmp, name))]
print("| scene | ranks | partitioner | first by work, reused / scratch | "
      "moved, reused | moved, from scratch | reused / scratch | "
      "largest repartitioning, reused / scratch (drifted) | a median repartitioning from scratch | "
      "MB moved, reused / scratch | "
      "work-weighted pair imbalance, reused / scratch | work-weighted modelled-cost imbalance, reused / scratch |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
names = sorted({os.path.basename(f).split("@")[1].rsplit("-", 2)[0]
                for f in glob.glob(os.path.join(tmp, "*.jsonl"))})
for scene, ranks, p in ((s, r, p) for s in scenes for r in (2, 4) for p in names):
    runs = {m: load("%s@%s-%d-%s.jsonl" % (scene, p, ranks, m)) for m in ("reuse", "fresh")}
    # The first interval holds the first partitioning, from the dealt
    # bodies, and the second the first weighed by work, not triangles: what
    # they move is what the start and the change of weights ask, reused or
    # not. The partitions that follow the drift come after.
    first = {m: sum(r[1]["per_rank"]["migrated_bodies"]) for m, r in runs.items()}
    moved = {m: [sum(l["per_rank"]["migrated_bodies"]) for l in r[2:]] for m, r in runs.items()}
    drifted = [sum(l["per_rank"]["drifted_bodies"]) for l in runs["reuse"][2:]]
    mb = {m: sum(sum(l["per_rank"]["migrated_bytes"]) for l in r[2:]) / 1e6 for m, r in runs.items()}
    # What the imbalance costs in time: the slowest rank's work summed over
    # the intervals against the mean's, so an interval weighs its work.
    def weighted(field):
        def of(r):
            v = [l["per_rank"][field] for l in r[1:]]
            return sum(max(x) for x in v) / max(1e-300, sum(sum(x) / len(x) for x in v))
        return {m: of(r) for m, r in runs.items()}
    pairs, cost = weighted("triangle_pairs"), weighted("modelled_work_ns")
    k = max(range(len(moved["fresh"])), key=lambda i: moved["fresh"][i], default=None)
    largest = "%d / %d (%d)" % (moved["reuse"][k], moved["fresh"][k], drifted[k]) if k is not None else "-"
    fresh_sorted = sorted(moved["fresh"])
    median = "%d" % fresh_sorted[len(fresh_sorted) // 2] if fresh_sorted else "-"
    a, b = sum(moved["reuse"]), sum(moved["fresh"])
    print("| %s | %d | %s | %d / %d | %d | %d | %.2f | %s | %s | %.2f / %.2f | %.3f / %.3f | %.3f / %.3f |" % (
        scene, ranks, p, first["reuse"], first["fresh"], a, b, a / b if b else 1.0, largest, median,
        mb["reuse"], mb["fresh"], pairs["reuse"], pairs["fresh"],
        cost["reuse"], cost["fresh"]))
print()
print("First by work: the bodies moved by the first repartitioning weighed by work (pairs) "
      "rather than triangles, which moves what the change of weights asks, reused or not. "
      "Moved: bodies that changed rank over the repartitionings after it, which follow the "
      "particles' drift. Largest "
      "repartitioning: the one that moved most from scratch, and what the reusing run moved at "
      "the same step; drifted: the bodies of the reusing run that had left their rank's region "
      "of its previous partition by then (metric `drifted_bodies`), what keeping every cut "
      "where it was would have moved. A median repartitioning from scratch: what the particles' drift alone moves "
      "over one interval, the floor under what a repartitioning that follows it can move. Imbalance: the most any rank did, summed over the 100-step intervals, over "
      "the mean's sum, so that an interval counts by its work, as it does in the run's time: of "
      "the triangle pairs checked, and of the work the partitioner balances, the `pairs` "
      "weight's modelled cost (each rank's bodies, body pairs and triangle pairs at their cost, "
      "docs/distributed.md, \"Weights\"). Triangle pairs alone leave out the bodies' own cost "
      "and the body pairs', and weigh a large particle's contacts as their many triangles.")
PY
