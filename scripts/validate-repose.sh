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
  # What the runs were made by, for the stamp when they are analysed later.
  echo "$(git rev-parse --short HEAD) $(date -u +%Y-%m-%d)" > "$runs/made"
fi
made=$(cat "$runs/made" 2>/dev/null || echo "$(git rev-parse --short HEAD) $(date -u +%Y-%m-%d)")
# The Debian python, where install-deps.sh puts numpy and h5py.
/usr/bin/python3 - "$runs" > out/validation/repose.md <<'PY'
import glob, math, os, sys
import h5py
import numpy as np

runs = sys.argv[1]
RING = (0.2, 0.8)   # the flank: this share of the heap's radius, apex and toe left out
BINS = 6            # rings across the flank, per quarter
BACK = 3            # output steps between the heap read and its earlier self

def heap(path, back=0):
    """The grains on the plate at the output step `back` steps before the last."""
    f = h5py.File(path, "r")
    steps = f["steps"]
    g = steps[str(len(steps) - 1 - back)]
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
for d in sorted((os.path.dirname(p) for p in glob.glob(os.path.join(runs, "*", "run.h5"))), key=lambda d: float(os.path.basename(d))):
    mu = float(os.path.basename(d))
    p, out, t = heap(os.path.join(d, "run.h5"))
    a, radius, height = flank_angles(p)
    secs = open(os.path.join(d, "seconds")).read().strip() if os.path.exists(os.path.join(d, "seconds")) else "-"
    cone = math.degrees(math.atan(height / radius))
    # Still creeping? The same measure BACK output steps earlier.
    early, _, t0 = heap(os.path.join(d, "run.h5"), BACK)
    drift = a.mean() - flank_angles(early)[0].mean()
    rows.append((mu, a.mean(), a.min(), a.max(), cone, len(p), out, radius, height, secs, a.std(ddof=1), drift, t - t0))

print("| grain μ | flank angle (°), mean of 4 quarters ± sd | their min – max | change over the last (s) | cone angle atan(H/R) (°) | grains on the plate | off the plate | heap radius R (mm) | height H (mm) | seconds |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r[0]:.1f} | {r[1]:.1f} ± {r[10]:.1f} | {r[2]:.1f} – {r[3]:.1f} | {r[11]:+.1f}° in {r[12]:.1f} | {r[4]:.1f} | {r[5]} | {r[6]} | {1e3*r[7]:.1f} | {1e3*r[8]:.1f} | {r[9]} |")
with open("out/validation/repose.csv", "w") as c:
    c.write("series,mu,angle_deg,error_deg,angle_min,angle_max,grains,off,radius_m,height_m,seconds\n")
    for r in rows:
        c.write(f"flank,{r[0]},{r[1]},{r[10]},{r[2]},{r[3]},{r[5]},{r[6]},{r[7]},{r[8]},{r[9]}\n")
        c.write(f"cone,{r[0]},{r[4]},,,,{r[5]},{r[6]},{r[7]},{r[8]},{r[9]}\n")
PY
$tridem chart out/validation/repose.csv --x mu --y angle_deg --by series --error error_deg \
  --y-from 15 --title "Angle of repose against grain friction: flank (± sd of 4 quarters), cone atan(H/R)" \
  --output docs/figures/repose.svg 2>/dev/null
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
{
  echo "Measured by \`scripts/validate-repose.sh\` on $cpu ($(nproc) cores), commit ${made% *}, ${made#* }; each heap read at its end_time, the flank angle per quarter from the highest grain in each of 6 rings between 0.2 and 0.8 of the heap's radius (the radius holding 95% of its grains)."
  echo
  cat out/validation/repose.md
} > out/validation/repose-table.md
cat out/validation/repose-table.md
