#!/usr/bin/env bash
# The dynamic angle of repose in a rotating drum, scenes/validation/drum-*.toml:
# runs the five speeds (each to its end_time), measures each bed's slope while
# the drum turns its second radian, and prints the results table of
# docs/validation.md ("Rotating drum"), stamped; the figure goes to
# docs/figures/drum.svg (and .png), the numbers to out/validation/drum.csv.
# About fifteen minutes on two cores.
# Usage: scripts/validate-drum.sh [RUN_DIR]   (RUN_DIR: analyse runs already
#        made there, as out/validation/drum/<Fr>/)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
cargo build --release -p experiments -q
tridem=target/release/tridem
runs=${1:-out/validation/drum}
mkdir -p out/validation docs/figures
if [ $# -eq 0 ]; then
  for scene in scenes/validation/drum-*.toml; do
    fr=$(basename "$scene" .toml); fr=${fr#drum-}
    start=$SECONDS
    $tridem run "$scene" --output "$runs/$fr" --overwrite --quiet >/dev/null
    echo $((SECONDS - start)) > "$runs/$fr/seconds"
  done
  # What the runs were made by, for the stamp when they are analysed later.
  echo "$(git rev-parse --short HEAD) $(date -u +%Y-%m-%d)" > "$runs/made"
fi
made=$(cat "$runs/made" 2>/dev/null || echo "$(git rev-parse --short HEAD) $(date -u +%Y-%m-%d)")
/usr/bin/python3 - "$runs" > out/validation/drum.md <<'PY'
import glob, math, os, sys
import h5py
import numpy as np

runs = sys.argv[1]
G, R, DT = 9.81, 0.08, 5e-5   # gravity (m/s^2), the drum's inner radius (m), the step (s)
SPIN = 0.4               # s: the drum turns at its full rate from here on
TURNED = (1.0, 2.0)      # rad turned since SPIN: the window measured
BINS = 6                 # across the middle of the surface, |x| < R/2

def angles(x, z):
    """The bed's slope two ways (degrees, positive when the bed is lifted
    towards -x, where the wall rises): from its centre of mass, which for a
    flat surface lies on the chord's perpendicular through the axis; and
    from a line through the highest grain of each of BINS columns."""
    com = math.degrees(math.atan2(-x.mean(), -z.mean()))
    edges = np.linspace(-R / 2, R / 2, BINS + 1)
    cx, top = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        inside = (x >= lo) & (x < hi)
        if inside.any():
            k = np.argmax(np.where(inside, z, -np.inf))
            cx.append(x[k]); top.append(z[k])
    slope = np.polyfit(cx, top, 1)[0] if len(cx) >= 3 else float("nan")
    return com, -math.degrees(math.atan(slope))

rows = []
for path in sorted(glob.glob(os.path.join(runs, "*", "run.h5")), key=lambda p: float(os.path.basename(os.path.dirname(p)))):
    fr = float(os.path.basename(os.path.dirname(path)))
    omega = math.sqrt(fr * G / R)
    f = h5py.File(path, "r")
    grain = f["bodies/mass"][:] > 0
    com, top = [], []
    for k in sorted(f["steps"].keys(), key=int):
        s = f["steps"][k]
        t = s.attrs["time"]
        turned = (t - SPIN) * omega
        if TURNED[0] <= turned <= TURNED[1]:
            p = s["positions"][:][grain]
            a, b = angles(p[:, 0], p[:, 2])
            com.append(a); top.append(b)
    if not com:
        sys.exit(f"{path}: no output step while the drum turns its second radian")
    com, top = np.array(com), np.array(top)
    half = len(com) // 2
    drift = com[half:].mean() - com[:half].mean()
    clock = os.path.join(os.path.dirname(path), "seconds")
    seconds = float(open(clock).read()) if os.path.exists(clock) else float("nan")
    end = max(f["steps"][k].attrs["time"] for k in f["steps"].keys())
    rows.append((fr, omega, com.mean(), com.std(ddof=1), top.mean(), top.std(ddof=1), drift, len(com), int(grain.sum()), end, seconds, com.min(), com.max()))

if not rows:
    sys.exit(f"no runs under {runs}")
with open("out/validation/drum.csv", "w") as out:
    out.write("froude,angle_deg,spread_deg,series\n")
    for fr, _, c, sc, t, st, *_ in rows:
        out.write(f"{fr:.0e},{c:.3f},{sc:.3f},centre of mass\n")
        out.write(f"{fr:.0e},{t:.3f},{st:.3f},surface line\n")
print("| Fr = ω²R/g | ω (rad/s) | angle, centre of mass (°) | its least and most | angle, surface line (°) | drift within the window (°) | samples | simulated (s) | steps | run (s) |")
print("|---|---|---|---|---|---|---|---|---|---|")
for fr, w, c, sc, t, st, drift, n, _, end, secs, lo, hi in rows:
    print(f"| {fr:.0e} | {w:.3f} | {c:.1f} ± {sc:.1f} | {lo:.1f} – {hi:.1f} | {t:.1f} ± {st:.1f} | {drift:+.1f} | {n} | {end:.2f} | {round(end / DT)} | {secs:.0f} |")
print()
grains = rows[0][8]
lo, hi = rows[0], rows[-1]
print(f"{grains} grains; R = {1000*R:.0f} mm. Each angle is the mean over the output steps while the drum "
      f"turns its second radian, ± their standard deviation (the bed's fluctuation, not an error of the "
      f"mean); the drift is the second half's mean less the first half's (centre of mass). From Fr = "
      f"{lo[0]:.0e} to {hi[0]:.0e} the centre-of-mass angle changes by {hi[2]-lo[2]:+.1f}°.")
PY
$tridem chart out/validation/drum.csv --x froude --y angle_deg --by series --error spread_deg \
  --log-x --y-from 20 --title "Dynamic angle of repose against the Froude number (± the bed's fluctuation)" \
  --output docs/figures/drum.svg 2>/dev/null
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/validate-drum.sh\` on $cpu ($(nproc) cores), commit ${made% *}, ${made#* }."
echo
cat out/validation/drum.md
