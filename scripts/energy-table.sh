#!/usr/bin/env bash
# How well the energy books close: for each scene, at its own time step and
# at a half and a quarter of it, the largest departure of the books' sum
# (kinetic + stored + dissipated) from its start over the run, against the
# largest kinetic energy of the run; and the steps a collision lasts
# (t_c = pi / omega at the scene's stable step's omega, over dt). Prints a
# markdown table.
# Usage: scripts/energy-table.sh [SCENE...] (default: two-particles, drop, hopper)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
cargo build --release -p experiments >&2
tridem=target/release/tridem
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(scenes/two-particles.toml scenes/drop.toml scenes/hopper.toml)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "| scene | dt (s) | steps per collision | books' drift / largest kinetic energy |"
echo "|---|---|---|---|"
for scene in "${scenes[@]}"; do
  dt0=$(grep -m1 '^dt' "$scene" | cut -d= -f2 | tr -d ' ')
  end=$(grep -m1 '^end_time' "$scene" | cut -d= -f2 | tr -d ' ')
  for f in 1 2 4; do
    dt=$(python3 -c "print($dt0 / $f)")
    n=$(python3 -c "print(int(round($end / $dt)))")
    rm -rf "$work/run"
    told=$($tridem run "$scene" --set "simulation.dt=$dt" --set "simulation.output_every=$(( n / 40 > 0 ? n / 40 : 1 ))" \
      --steps "$n" --output "$work/run" --quiet 2>&1 >/dev/null)
    $tridem plot "$work/run" --energy 2>/dev/null
    python3 - "$scene" "$dt" "$work/run/energy.csv" "$told" <<'PY'
import csv, math, re, sys
scene, dt, path, told = sys.argv[1], float(sys.argv[2]), sys.argv[3], sys.argv[4]
rows = list(csv.DictReader(open(path)))
total = [float(r["total"]) for r in rows]
kinetic = max(float(r["kinetic_translation"]) + float(r["kinetic_rotation"]) for r in rows)
drift = max(abs(t - total[0]) for t in total)
m = re.search(r"stable: ([0-9.e+-]+) s", told)
stable = float(m.group(1)) if m else None
# The stable step is h = (2/omega)(sqrt(1 + zeta^2) - zeta): omega from h
# needs zeta; without it, t_c = pi/omega is at least pi h / 2.
steps = f"≥ {math.pi * stable / 2 / dt:.1f}" if stable else "-"
print(f"| {scene} | {dt:.3g} | {steps} | {drift / kinetic:.4f} |")
PY
  done
done
