#!/usr/bin/env bash
# Beverloo's law on the silo of scenes/validation/beverloo-*.toml: runs the
# five outlet widths (each to its end_time), measures each discharge rate
# from the `outlet` probe (its slope while the twentieth to the fifth of
# the fill leaves), fits the law, and prints the results table of
# docs/validation.md ("Discharge through a slot"), stamped; the figure goes
# to docs/figures/beverloo.svg (and .png), the numbers to
# out/validation/beverloo.csv. About half an hour on two cores.
# Usage: scripts/validate-beverloo.sh [RUN_DIR]   (RUN_DIR: analyse runs
#        already made there, as out/validation/beverloo/<width>/)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
cargo build --release -p experiments -q
tridem=target/release/tridem
runs=${1:-out/validation/beverloo}
mkdir -p out/validation docs/figures
if [ $# -eq 0 ]; then
  for scene in scenes/validation/beverloo-*.toml; do
    w=$(basename "$scene" .toml); w=${w#beverloo-}
    start=$SECONDS
    $tridem run "$scene" --output "$runs/$w" --overwrite --quiet >/dev/null
    echo $((SECONDS - start)) > "$runs/$w/seconds"
  done
  # What the runs were made by, for the stamp when they are analysed later.
  echo "$(git rev-parse --short HEAD) $(date -u +%Y-%m-%d)" > "$runs/made"
fi
made=$(cat "$runs/made" 2>/dev/null || echo "$(git rev-parse --short HEAD) $(date -u +%Y-%m-%d)")
/usr/bin/python3 - "$runs" > out/validation/beverloo.md <<'PY'
import glob, math, os, sys
import h5py
import numpy as np

runs = sys.argv[1]
G, L = 9.81, 0.05             # gravity (m/s^2), the slot's length (the silo's depth, m)
BED = 0.10 * 0.04 * 0.06      # the `bed` probe's volume (m^3)
WINDOW = (0.05, 0.2)          # the share of the fill that has left: flowing, still high
OPEN = 0.75                   # s: the gate starts to uncover the slot
PARTS = 3                     # sub-windows: the spread of the rate within a run

def series(path):
    f = h5py.File(path, "r")
    steps = sorted(f["steps"].keys(), key=int)
    t = np.array([f["steps"][k].attrs["time"] for k in steps])
    probes = [f["steps"][k]["probes"].attrs for k in steps]
    # What has left: past the outlet plane and still falling, or taken
    # out of the run below it by the outflow.
    past = np.array([p["outlet_mass_past"] + p.get("outflow_mass", 0.0) for p in probes])
    bed = np.array([p["bed_mass"] for p in probes])
    mass = f["bodies/mass"][:]
    grains = mass[mass > 0]
    return t, past, bed, grains

def slope(t, m):
    return np.polyfit(t, m, 1)[0]

rows = []
for d in sorted(glob.glob(os.path.join(runs, "*", "run.h5"))):
    width = int(os.path.basename(os.path.dirname(d))) / 1000.0
    t, past, bed, grains = series(d)
    fill = grains.sum()
    inside = (past >= WINDOW[0] * fill) & (past <= WINDOW[1] * fill)
    W = slope(t[inside], past[inside])
    parts = [slope(t[k], past[k]) for k in np.array_split(np.flatnonzero(inside), PARTS)]
    err = np.std(parts, ddof=1) / math.sqrt(PARTS)
    settled = t <= OPEN + 1e-12
    rho_b = bed[settled][-1] / BED
    sec = os.path.join(os.path.dirname(d), "seconds")
    secs = open(sec).read().strip() if os.path.exists(sec) else "-"
    rows.append((width, W, err, rho_b, grains, t[-1], secs))

if not rows:
    sys.exit(f"no runs under {runs}")
grains = rows[0][4]
rho_p = 2500.0
d = (6 * grains.mean() / (math.pi * rho_p)) ** (1 / 3)  # volume-equivalent diameter
D = np.array([r[0] for r in rows])
W = np.array([r[1] for r in rows])
E = np.array([r[2] for r in rows])
rho_b = np.mean([r[3] for r in rows])

# Beverloo for a slot: W = C rho_b sqrt(g) L (D - k d)^(3/2), so W^(2/3) is
# linear in D; weighted by the errors of W^(2/3).
y, sy = W ** (2 / 3), (2 / 3) * W ** (-1 / 3) * E
wts = 1 / np.maximum(sy, 1e-12) ** 2
A = np.vstack([D, np.ones_like(D)]).T
cov = np.linalg.inv(A.T @ (A * wts[:, None]))
a, b = cov @ (A.T @ (wts * y))
k = -b / (a * d)
C = a ** 1.5 / (rho_b * math.sqrt(G) * L)
sa, sb = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
sk = abs(k) * math.sqrt((sb / b) ** 2 + (sa / a) ** 2) if b != 0 else float("nan")
sC = C * 1.5 * sa / a
# The exponent left free: W = c (D - D0)^n, D0 by least squares over a grid.
best = None
for D0 in np.linspace(0.0, 0.98 * D.min(), 400):
    X = np.log(D - D0)
    n, lc = np.polyfit(X, np.log(W), 1)
    res = np.sum((np.log(W) - (n * X + lc)) ** 2)
    if best is None or res < best[0]:
        best = (res, n, D0)
_, n_free, D0 = best
# The free exponent's uncertainty: the fit repeated on rates drawn within
# their errors (a parametric bootstrap, fixed seed).
rng = np.random.default_rng(1)
draws = []
for _ in range(300):
    Wd = np.maximum(W + E * rng.standard_normal(len(W)), 1e-9)
    fits = []
    for D0d in np.linspace(0.0, 0.98 * D.min(), 100):
        X = np.log(D - D0d)
        nd, lc = np.polyfit(X, np.log(Wd), 1)
        fits.append((np.sum((np.log(Wd) - (nd * X + lc)) ** 2), nd))
    draws.append(min(fits)[1])
s_n = float(np.std(draws, ddof=1))
pred = (a * (D - k * d)) ** 1.5

with open("out/validation/beverloo.csv", "w") as f:
    f.write("width_mm,rate_kg_s,error_kg_s,series\n")
    for Di, Wi, Ei in zip(D, W, E):
        f.write(f"{1000*Di:.0f},{Wi:.5f},{Ei:.5f},measured\n")
    for Di in np.linspace(max(k * d, 0.8 * D.min()), D.max() * 1.05, 40):
        f.write(f"{1000*Di:.2f},{(a * (Di - k * d)) ** 1.5:.5f},,Beverloo fit\n")

print("| slot width D (mm) | D / d | discharge rate W (kg/s) | Beverloo fit (kg/s) | fit − measured, in errors | grains | simulated (s) | run (s) |")
print("|---|---|---|---|---|---|---|---|")
for Di, Wi, Ei, Pi, r in zip(D, W, E, pred, rows):
    print(f"| {1000*Di:.0f} | {Di/d:.2f} | {Wi:.4f} ± {Ei:.4f} | {Pi:.4f} | {(Pi-Wi)/Ei:+.1f} | {len(r[4])} | {r[5]:.2f} | {r[6]} |")
print()
print(f"Grains: d = {1000*d:.2f} mm (volume-equivalent diameter), ρ_b = {rho_b:.0f} kg/m³ "
      f"(the settled bed, `bed` probe, mean of the runs), L = {1000*L:.0f} mm.")
print()
chi2 = float(np.sum(((pred - W) / E) ** 2))
print(f"Fitted with the exponent 3/2 (W^(2/3) linear in D, weighted): "
      f"C = {C:.3f} ± {sC:.3f}, k = {k:.2f} ± {sk:.2f}; "
      f"χ² = {chi2:.1f} for {len(D) - 2} degrees of freedom. "
      f"With the exponent free (W = c (D − D0)^n): n = {n_free:.2f} ± {s_n:.2f} "
      f"(the spread of 300 refits to rates drawn within their errors), D0 = {1000*D0:.1f} mm "
      f"({D0/d:.2f} d).")
PY
$tridem chart out/validation/beverloo.csv --x width_mm --y rate_kg_s --by series --error error_kg_s \
  --title "Discharge rate through a slot against its width (Beverloo fit, exponent 3/2)" \
  --output docs/figures/beverloo.svg 2>/dev/null
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/validate-beverloo.sh\` on $cpu ($(nproc) cores), commit ${made% *}, ${made#* }; each rate is the slope of the mass that has left while the twentieth to the fifth of the fill leaves, ± the standard error of the slopes of its three thirds."
echo
cat out/validation/beverloo.md
