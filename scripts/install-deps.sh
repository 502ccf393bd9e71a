#!/usr/bin/env bash
# Installs the Debian packages tridem builds against, only those missing.
# Idempotent: when everything is present it says so and changes nothing.
# Usage: scripts/install-deps.sh [--slurm] [--render]
set -euo pipefail

packages=(
  libtrilinos-zoltan-dev  # Zoltan headers and libtrilinos_zoltan (pulls Open MPI)
  libopenmpi-dev          # MPI headers and mpicc, used by rsmpi's build and zoltan-sys
  openmpi-bin             # mpirun
  libhdf5-dev             # serial HDF5 for output
  libclang-dev            # bindgen (zoltan-sys, mpi-sys, hdf5-sys)
  pkg-config
  cmake                   # the metis crate builds its vendored METIS with cmake
  python3-numpy           # the validation scripts' fits (scripts/validate-*.sh)
  python3-h5py            # and their reading of run.h5
  valgrind                # scripts/work-overhead.sh counts instructions with callgrind
)
for flag in "$@"; do
  case "$flag" in
    --slurm) packages+=(slurm-wlm munge) ;;
    # ParaView's pvbatch, with which the tests read run.xmf as ParaView does.
    --render) packages+=(paraview python3-paraview) ;;
    *) echo "install-deps: unknown option $flag (--slurm, --render)" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install-deps: all system packages present (${packages[*]})"
  exit 0
fi

echo "install-deps: installing missing packages: ${missing[*]}"
sudo=""
if [[ $(id -u) -ne 0 ]]; then
  if command -v sudo >/dev/null; then sudo="sudo"; else
    echo "install-deps: not root and no sudo; install as root: apt-get install ${missing[*]}" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "install-deps: done"
