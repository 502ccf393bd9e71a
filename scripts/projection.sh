#!/usr/bin/env bash
# A projection of the paper's run (Krestenitis, Weinzierl, Koziara, ACME
# 2016, Fig. 2: 10,000 particles, 25 M triangles, 1,000 steps) to 64-1,024
# ranks, from inputs measured here (a table of docs/tables.md, written by
# scripts/tables.sh; the model is in docs/distributed.md, "Projection"):
#  - latency and bandwidth between two ranks (tridem pingpong);
#  - ghosts, neighbours and local bodies per rank of the 10,000-particle silo
#    at 2-64 ranks, with every partitioner (oversubscribed: counts, not
#    times; the silo has the paper's particle count, so its ghost counts
#    per rank are the paper's at the same P), resumed from its state after
#    3,000 steps (the lower layers landed, the upper ones falling: work
#    that varies across the domain) for 60 steps, repartitioned every 20;
#  - the cost of a triangle-step on one thread, in a dense scene
#    (hopper-400) and a dilute one (the falling silo).
# The same runs give the counts at scale, one figure per measure against P
# (docs/figures/counts-*.svg, .png; the numbers in out/projection/counts.csv):
# ghosts per rank, bodies and bytes migrated per repartitioning, and the
# imbalance (max / mean over ranks) of the triangle pairs and contacts.
# Usage: scripts/projection.sh [MAX_RANKS]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
max=${1:-64}
cargo build --release -p experiments >&2
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
tridem=target/release/tridem
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mpirun --oversubscribe -np 2 $tridem pingpong --json > "$tmp/pingpong.json"
$tridem run scenes/hopper-400.toml --threads 1 --json --quiet 2>/dev/null > "$tmp/dense.json"
$tridem run scenes/silo.toml --steps 1000 --threads 1 --json --quiet 2>/dev/null > "$tmp/dilute.json"
$tridem run scenes/silo.toml --steps 3000 --quiet --output "$tmp/settled" >/dev/null 2>&1
for p in $($tridem partition --list); do
  for ranks in 2 4 8 16 32 64; do
    [ "$ranks" -gt "$max" ] && continue
    mpirun --oversubscribe -np "$ranks" $tridem run scenes/silo.toml --steps 60 --quiet --json \
      --resume "$tmp/settled/checkpoint.h5" --output "$tmp/out-$p-$ranks" \
      --partitioner "$p" --repartition-every 20 --metrics "$tmp/$p-$ranks.jsonl" --metrics-every 20 \
      2>/dev/null > "$tmp/$p-$ranks.json"
  done
done
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/projection.sh $max\` on $cpu ($(nproc) cores), commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d)."
echo
python3 - "$tmp" "$max" <<'PY'
import json, sys, glob, os, math
tmp, top = sys.argv[1], int(sys.argv[2])
load = lambda f: json.load(open(os.path.join(tmp, f)))
pp = load("pingpong.json")
alpha, beta = pp["latency_seconds"], pp["bandwidth_bytes_per_second"]
cost = {}
for kind in ("dense", "dilute"):
    j = load(kind + ".json")
    tri = j["particles"] * {"dense": 20, "dilute": 20}[kind]
    cost[kind] = j["seconds"] / j["steps"] / tri
print("Inputs: latency %.3f us and bandwidth %.2f GB/s between two ranks (`tridem pingpong`); "
      "one thread's cost per triangle-step %.1f ns dense (hopper-400, 7,000 steps) and %.1f ns dilute "
      "(silo, 1,000 steps of its fall)." % (1e6 * alpha, beta / 1e9, 1e9 * cost["dense"], 1e9 * cost["dilute"]))
print()
print("Counts on the silo (10,000 particles of 20 triangles) resumed after 3,000 steps for 60, "
      "repartitioned every 20, oversubscribed: ghosts per rank (mean / max), neighbours per rank (max), "
      "ghost share (ghosts / owned, mean).")
print()
parts = sorted({os.path.basename(f).rsplit("-", 1)[0] for f in glob.glob(os.path.join(tmp, "*-*.json"))
                if not f.endswith(("pingpong.json",))})
ranks = sorted({int(os.path.basename(f).rsplit("-", 1)[1][:-5]) for f in glob.glob(os.path.join(tmp, "*-*.json"))
                if os.path.basename(f).rsplit("-", 1)[1][:-5].isdigit()})
print("| partitioner | " + " | ".join("P = %d" % p for p in ranks) + " |")
print("|---|" + "---|" * len(ranks))
fit = {}
for part in parts:
    cells, xs, ys = [], [], []
    for p in ranks:
        t = load("%s-%d.json" % (part, p))["per_step_over_ranks"]
        g, o, n = t["ghosts_received"], t["owned_bodies"], t["neighbours"]
        cells.append("%.0f / %.0f, %.0f, %.2f" % (g["mean"], g["max"], n["max"], g["mean"] / o["mean"]))
        if p >= 4:
            xs.append(math.log(10000 / p)); ys.append(math.log(g["max"]))
    # ghosts per rank ~ c (N/P)^e: the surface of a rank's region.
    k = len(xs); mx, my = sum(xs) / max(k, 1), sum(ys) / max(k, 1)
    sxx = sum((x - mx) ** 2 for x in xs)
    e = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else float("nan")
    fit[part] = (math.exp(my - e * mx), e)
    print("| %s | %s |" % (part, " | ".join(cells)))
print()
print("Fitted ghosts per rank (the largest rank's) g = c (N/P)^e, over P = 4-%d: " % ranks[-1]
      + "; ".join("%s e = %.2f" % (p, fit[p][1]) for p in parts) + " (a surface in 3-D: e = 2/3).")
print()
# Counts at scale: per partitioner and P, from the metrics' intervals after
# the first (which holds the partition of the dealt particles).
rows = ["partitioner,ranks,ghosts_max,migrated_bodies,migrated_megabytes,pair_imbalance,contact_imbalance"]
def imbalance(v):
    m = sum(v) / len(v)
    return max(v) / m if m > 0 else 1.0
for part in parts:
    for p in ranks:
        g = load("%s-%d.json" % (part, p))["per_step_over_ranks"]["ghosts_received"]["max"]
        lines = [json.loads(l) for l in open(os.path.join(tmp, "%s-%d.jsonl" % (part, p)))][1:]
        k = max(1, len(lines))
        moved = sum(sum(l["per_rank"]["migrated_bodies"]) for l in lines) / k
        mb = sum(sum(l["per_rank"]["migrated_bytes"]) for l in lines) / k / 1e6
        pairs = sum(imbalance(l["per_rank"]["triangle_pairs"]) for l in lines) / k
        contacts = sum(imbalance(l["per_rank"]["contacts"]) for l in lines) / k
        rows.append("%s,%d,%.1f,%.1f,%.4f,%.4f,%.4f" % (part, p, g, moved, mb, pairs, contacts))
os.makedirs("out/projection", exist_ok=True)
open("out/projection/counts.csv", "w").write("\n".join(rows) + "\n")
print("Counts at scale (the same runs): the largest rank's ghosts, the bodies and megabytes one "
      "repartitioning migrates (summed over ranks, mean over the repartitionings after the first), and the "
      "imbalance (max / mean over ranks, mean over the 20-step intervals) of the triangle pairs checked and "
      "of the contacts; the numbers are out/projection/counts.csv.")
print()
for name in ["ghosts_max", "migrated_bodies", "migrated_megabytes", "pair_imbalance", "contact_imbalance"]:
    print("![%s against ranks](figures/counts-%s.svg)" % (name, name.replace("_", "-")))
    print()
# The paper's run: 10,000 particles of 2,500 triangles.
N, T = 10000, 25_000_000
motion, record = 104, 336
part = "zoltan-rcb"
c, e = fit[part]
print("Projection of the paper's run (%s, its largest rank; the compute is one thread's per rank): per step, "
      "the compute of a rank's owned and ghost triangles, and the exchange of the ghosts' motions "
      "(%d B each) with its neighbours; memory per rank: 128 B per triangle and 1 KB per body held, "
      "and the 26 MB of the MPI runtime. Blocking, the exchange adds to the step; non-blocking, only "
      "what the local detection (taken as the owned bodies' share of the compute) does not hide."
      % (part, motion))
print()
print("| ranks | particles per rank | ghosts per rank | compute dense (ms/step) | compute dilute (ms/step) | exchange (us/step) | blocking step, dense (ms) | non-blocking wait, dilute (us) | memory per rank (MB) |")
print("|---|---|---|---|---|---|---|---|---|")
nb_max = max(load("%s-%d.json" % (part, p))["per_step_over_ranks"]["neighbours"]["max"] for p in ranks)
for p in [64, 128, 256, 512, 1024]:
    own = N / p
    ghosts = min(c * (N / p) ** e, N - own)
    held = own + ghosts
    tri = held * T / N
    dense, dilute = cost["dense"] * tri, cost["dilute"] * tri
    exchange = nb_max * alpha + ghosts * motion / beta
    local = cost["dilute"] * own * T / N
    nonblocking = max(0.0, exchange - local)
    memory = tri * 128 + held * 1024 + 26e6
    print("| %d | %.0f | %.0f | %.1f | %.2f | %.1f | %.1f | %.1f | %.0f |" % (
        p, own, ghosts, 1e3 * dense, 1e3 * dilute, 1e6 * exchange, 1e3 * (dense + exchange),
        1e6 * nonblocking, memory / 1e6))
PY
charts=(
  "ghosts_max:ghosts received per step, the largest rank's:"
  "migrated_bodies:bodies migrated per repartitioning:"
  "migrated_megabytes:MB migrated per repartitioning:"
  "pair_imbalance:triangle pairs checked, max / mean over ranks:1"
  "contact_imbalance:contacts, max / mean over ranks:1"
)
for c in "${charts[@]}"; do
  IFS=: read -r y title from <<< "$c"
  $tridem chart out/projection/counts.csv --x ranks --y "$y" --by partitioner --log-x \
    ${from:+--y-from "$from"} --title "silo, 10,000 particles: $title" \
    --output "docs/figures/counts-${y//_/-}.svg" 2>/dev/null
done
