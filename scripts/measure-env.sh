# Sourced by the scripts that measure and write docs/ (reproduce.sh,
# tables.sh), from the repository's root: builds tridem, lets Open MPI run
# as root, and sets `tridem` (the binary), `cores` and `stamp` (CPU model,
# cores, commit and date, for the pages).
source scripts/env.sh
cargo build --release -p experiments >&2
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
tridem=target/release/tridem
cores=$(nproc)
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
stamp="$cpu, $cores cores, commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d)"
