#!/usr/bin/env bash
# The work the ranks add to one process's, counted and not timed: the
# instructions each process executes in its steps (valgrind's callgrind,
# collecting inside the step loop only: no start-up, no MPI_Init), less
# those in MPI's own libraries (a rank polling for a message is waiting,
# not working), summed over the ranks, over one process's. The same count
# on every run of the same build, so a change of a percent shows without
# repeats, on a machine whose times vary by more than that; and the
# per-rank counts give the ranks' imbalance of work, free of the cores'
# speeds. Instructions are not time (a cache miss costs more than an add):
# the timed ratios are those of scripts/distributed-table.sh.
# Callgrind runs the code some 30 times slower, and sees no AVX-512: the
# kernels run their AVX2 variants under it.
# Usage: scripts/work-overhead.sh [RANKS]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
ranks=${1:-2}
command -v valgrind >/dev/null || {
  echo "work-overhead: needs valgrind (scripts/install-deps.sh installs it)" >&2
  exit 1
}
cargo build --release -p experiments >&2
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
tridem=target/release/tridem
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
# callgrind LABEL COMMAND...: COMMAND under callgrind, a file per process.
callgrind() {
  valgrind --tool=callgrind --toggle-collect='*run_steps*' \
    --callgrind-out-file="$dir/$1.%p" "${@:2}"
}
# Per file (one per process) of the label: [work, MPI's own], in instructions.
split() {
  python3 - "$dir" "$1" <<'EOF'
import glob, re, subprocess, sys
mpi = re.compile(r"libmpi|libopen-pal|libopen-rte|/openmpi/|mca_|pmix|libuc[pst]|hwloc|libevent|libfabric")
out = []
for f in sorted(glob.glob(f"{sys.argv[1]}/{sys.argv[2]}.*")):
    text = subprocess.run(["callgrind_annotate", "--threshold=100", "--auto=no", f],
                          capture_output=True, text=True, check=True).stdout
    listing = text.split("file:function", 1)[1].split("\n", 2)[2]
    work = own = 0
    for line in listing.splitlines():
        m = re.match(r"\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(.*)$", line)
        if not m:
            continue
        n = int(m.group(1).replace(",", ""))
        if mpi.search(m.group(2)):
            own += n
        else:
            work += n
    out.append(f"{work} {own}")
print(" ".join(out))
EOF
}
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/work-overhead.sh $ranks\` on $cpu, commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d); instructions in the steps, one run each (a count: the same on every run)."
echo
echo "| scene | steps | one process (G instr.) | $ranks ranks, summed | ranks / one process | work imbalance (max / mean) | MPI's own, summed (polling while waiting) |"
echo "|---|---|---|---|---|---|---|"
for spec in silo-1000.toml:1500 hopper-400.toml:3000 silo.toml:200; do
  scene=scenes/${spec%%:*}; steps=${spec##*:}
  rm -f "$dir"/*
  run=(run "$scene" --steps "$steps" --threads 1 --quiet)
  callgrind one $tridem "${run[@]}" >/dev/null 2>&1
  mpirun --oversubscribe -np "$ranks" bash -c "$(declare -f callgrind); dir=$dir; callgrind ranks $tridem ${run[*]}" >/dev/null 2>&1
  python3 - "$scene" "$steps" "$(split one)" "$(split ranks)" <<'EOF'
import sys
scene, steps, one, ranks = sys.argv[1:]
one = [int(x) for x in one.split()][0]
v = [int(x) for x in ranks.split()]
work, own = v[0::2], v[1::2]
total = sum(work)
print(f"| {scene} | {steps} | {one/1e9:.3f} | {total/1e9:.3f} | {total/one:.3f} "
      f"| {max(work)/(total/len(work)):.3f} | {sum(own)/1e9:.3f} |")
EOF
done
