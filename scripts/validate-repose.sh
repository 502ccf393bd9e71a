#!/usr/bin/env bash
# The angle of repose of poured hulls against their friction,
# scenes/validation/repose-*.toml: runs the four frictions (each to its
# end_time, two at a time), measures each heap's flank, and prints the
# results table of docs/validation.md ("Angle of repose"), stamped; the
# figure goes to docs/figures/repose.svg (and .png), the numbers to
# out/validation/repose.csv.
# Usage: scripts/validate-repose.sh [RUN_DIR]   (RUN_DIR: analyse runs already
#        made there, as out/validation/repose/<mu>/)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
cargo build --release -p experiments -q
tridem=target/release/tridem
runs=${1:-out/validation/repose}
mkdir -p out/validation docs/figures
if [ $# -eq 0 ]; then
  for scene in scenes/validation/repose-*.toml; do
    mu=$(basename "$scene" .toml); mu=${mu#repose-}
    (start=$SECONDS
     $tridem run "$scene" --output "$runs/$mu" --overwrite --quiet --threads 1 >/dev/null
     echo $((SECONDS - start)) > "$runs/$mu/seconds") &
    # Two at a time, one per core.
    while [ "$(jobs -rp | wc -l)" -ge 2 ]; do sleep 1; done
  done
  wait
fi
/usr/bin/env python3 - "$runs" > out/validation/repose.md <<'PY'
import glob, math, os, sys
import h5py
import numpy as np

runs = sys.argv[1]
RING = (0.2, 0.8)   # the flank: this share of the heap's radius, apex and toe left out
BINS = 6            # rings across the flank, per quarter

def heap(path):
    f = h5py.File(path, "r")
    steps = f["steps"]
    g = steps[str(len(steps) - 1)]
    x = g["positions"][()]
    out = (g["removed"][()] == 1) | (g["pending"][()] == 1)
    keep = ~out
    keep[-1] = False   # the plate: the scene's one obstacle, after the grains
    return x[keep], int(out.sum()), g.attrs["time"]

def flank_angles(p):
    """The heap's slope in each quarter around its axis (degrees): the
    highest grain of each of BINS rings across the flank, a line fitted."""
    rho = np.hypot(p[:, 0], p[:, 1])
    radius = np.quantile(rho, 0.95)
    phi = np.arctan2(p[:, 1], p[:, 0])
    angles = []
    for q in range(4):
        lo_phi = -math.pi + q * math.pi / 2
        sector = (phi >= lo_phi) & (phi < lo_phi + math.pi / 2)
        edges = np.linspace(RING[0] * radius, RING[1] * radius, BINS + 1)
        r, z = [], []
        for a, b in zip(edges[:-1], edges[1:]):
            inside = sector & (rho >= a) & (rho < b)
            if inside.any():
                k = np.argmax(np.where(inside, p[:, 2], -np.inf))
                r.append(rho[k]); z.append(p[k, 2])
        if len(r) >= 3:
            angles.append(-math.degrees(math.atan(np.polyfit(r, z, 1)[0])))
    return np.array(angles), radius, p[:, 2].max()

rows = []
for d in sorted(glob.glob(os.path.join(runs, "*")), key=lambda d: float(os.path.basename(d))):
    mu = float(os.path.basename(d))
    p, out, t = heap(os.path.join(d, "run.h5"))
    a, radius, height = flank_angles(p)
    secs = open(os.path.join(d, "seconds")).read().strip() if os.path.exists(os.path.join(d, "seconds")) else "-"
    cone = math.degrees(math.atan(height / radius))
    rows.append((mu, a.mean(), a.min(), a.max(), cone, len(p), out, radius, height, secs))

print("| grain μ | flank angle (°), mean of 4 quarters | min – max | cone angle atan(H/R) (°) | grains on the plate | off the plate | heap radius R (mm) | height H (mm) | seconds |")
print("|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r[0]:.1f} | {r[1]:.1f} | {r[2]:.1f} – {r[3]:.1f} | {r[4]:.1f} | {r[5]} | {r[6]} | {1e3*r[7]:.1f} | {1e3*r[8]:.1f} | {r[9]} |")
with open("out/validation/repose.csv", "w") as c:
    c.write("mu,angle_mean,angle_min,angle_max,cone_angle,grains,off,radius_m,height_m,seconds\n")
    for r in rows:
        c.write(",".join(str(v) for v in r) + "\n")
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
fig, ax = plt.subplots(figsize=(5.5, 3.8))
mu = [r[0] for r in rows]
mean = np.array([r[1] for r in rows])
ax.errorbar(mu, mean, yerr=[mean - [r[2] for r in rows], [r[3] for r in rows] - mean],
            fmt="o", capsize=4, label="flank (4 quarters, min–max)")
ax.plot(mu, [r[4] for r in rows], "s", mfc="none", label="cone atan(H/R)")
ax.set_xlabel("grain friction μ")
ax.set_ylabel("angle of repose (°)")
ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), frameon=False)
ax.set_xticks(mu)
fig.tight_layout()
for ext in ("svg", "png"):
    fig.savefig(f"docs/figures/repose.{ext}", dpi=120)
PY
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
{
  echo "Measured by \`scripts/validate-repose.sh\` on $cpu ($(nproc) cores), commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d); each heap read at its end_time, the flank angle per quarter from the highest grain in each of 6 rings between 0.2 and 0.8 of the heap's radius (the radius holding 95% of its grains)."
  echo
  cat out/validation/repose.md
} > out/validation/repose-table.md
cat out/validation/repose-table.md
