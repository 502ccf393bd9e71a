#!/usr/bin/env bash
# The cost model of the `pairs` weight (distributed/src/weights.rs, COST),
# fitted and checked on the distributed DEM itself (docs/distributed.md,
# "Weights"):
#  - each scene runs on 2 ranks x 1 thread, REPEAT times, with a metrics
#    line every 20 steps;
#  - per rank and interval, the busy time less partitioning and migration
#    (what a particle's contacts and motion cost) is fitted, by least squares
#    with rates >= 0, to the bodies in the run, the body pairs and the
#    triangle pairs examined there, on the FIT scenes only;
#  - on every scene, fitted or not, it prints what the fitted rates and the
#    shipped ones (each rank's modelled work) predict: the busy time summed
#    (predicted / measured) and, interval by interval, the difference between
#    the two ranks' busy times (its correlation with the measured one), which
#    is what the partitioner has to see to balance.
# Usage: scripts/weights-fit.sh [REPEAT]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
repeat=${1:-3}
fit="hopper.toml:7000 silo-1000.toml:3000"
check="hopper-400.toml:7000 collapse.toml:2000 silo-offset.toml:2000 mixed.toml:1000 silo.toml:1000"
cargo build --release -p experiments >&2
tridem=target/release/tridem
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
for r in $(seq "$repeat"); do
  for spec in $fit $check; do
    name=${spec%%:*}
    mpirun --oversubscribe -np 2 $tridem run "scenes/$name" --steps "${spec##*:}" --threads 1 --quiet \
      --metrics "$dir/$name.$r.jsonl" --metrics-every 20 >/dev/null 2>&1
  done
done
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/weights-fit.sh $repeat\` on $cpu ($(nproc) cores), commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d); 2 ranks x 1 thread, $repeat runs per scene, 20-step intervals."
echo
python3 - "$dir" "$fit" "$check" <<'EOF'
import glob, itertools, json, sys
import numpy as np

directory, fit, check = sys.argv[1], sys.argv[2].split(), sys.argv[3].split()
names = [s.split(":")[0] for s in fit + check]
FEATURES = ["present_bodies", "body_pairs", "triangle_pairs"]

def intervals(name):
    """Per 20-step interval and rank: the features, the busy time, the shipped model."""
    X, y, shipped = [], [], []
    for path in sorted(glob.glob(f"{directory}/{name}.*.jsonl")):
        for line in open(path).readlines()[1:]:  # the first carries the start
            p = json.loads(line)["per_rank"]
            ranks = range(len(p["busy_seconds"]))
            X.append([[p[f][k] for f in FEATURES] for k in ranks])
            y.append([p["busy_seconds"][k] - p["partition_seconds"][k]
                      - p["migration_seconds"][k] for k in ranks])
            shipped.append([1e-9 * p["modelled_work_ns"][k] for k in ranks])
    return np.array(X), np.array(y), np.array(shipped)

data = {n: intervals(n) for n in names}

def non_negative_fit(A, b):
    """Least squares over rates >= 0: the best of the unconstrained fits on
    every subset of the features whose rates all come out >= 0."""
    best = None
    for r in range(1, A.shape[1] + 1):
        for cols in itertools.combinations(range(A.shape[1]), r):
            c = np.linalg.lstsq(A[:, cols], b, rcond=None)[0]
            if (c >= 0).all():
                x = np.zeros(A.shape[1]); x[list(cols)] = c
                res = ((A @ x - b) ** 2).sum()
                if best is None or res < best[0]:
                    best = (res, x)
    return best[1]

fitted = [s.split(":")[0] for s in fit]
A = np.concatenate([data[n][0].reshape(-1, len(FEATURES)) for n in fitted])
b = np.concatenate([data[n][1].reshape(-1) for n in fitted])
rates = non_negative_fit(A, b)
print("Fitted rates (ns): " + ", ".join(
    f"{f} {1e9 * r:.0f}" for f, r in zip(["per body and step", "per body pair", "per triangle pair"], rates)) + ".")
print()
print("| scene | role | intervals | busy per rank-step (us) | fitted: predicted / measured | fitted: rank difference, correlation | shipped: predicted / measured | shipped: rank difference, correlation |")
print("|---|---|---|---|---|---|---|---|")

def corr(pred, y):
    d, m = pred[:, 0] - pred[:, 1], y[:, 0] - y[:, 1]
    return float(np.corrcoef(d, m)[0, 1]) if d.std() > 0 and m.std() > 0 else float("nan")

for spec in fit + check:
    name, steps = spec.split(":")
    X, y, shipped = data[name]
    pred = X @ rates
    rank_steps = y.size * 20
    print(f"| {name} | {'fit' if spec in fit else 'check'} | {len(y)} | {1e6 * y.sum() / rank_steps:.1f} "
          f"| {pred.sum() / y.sum():.2f} | {corr(pred, y):.2f} | {shipped.sum() / y.sum():.2f} | {corr(shipped, y):.2f} |")
EOF
