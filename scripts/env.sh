# Sourced by the project's scripts: environment for running Open MPI on one machine.
# As root (containers, CI) Open MPI refuses to start without these two.
if [[ $(id -u) -eq 0 ]]; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
# Containers often forbid the cross-memory attach that shared memory uses by default.
export OMPI_MCA_btl_vader_single_copy_mechanism=${OMPI_MCA_btl_vader_single_copy_mechanism:-none}
# Make sure cargo is on PATH when called from a non-login shell (rustup default location).
if ! command -v cargo >/dev/null 2>&1 && [[ -f "$HOME/.cargo/env" ]]; then
  # shellcheck disable=SC1091
  source "$HOME/.cargo/env"
fi
# The measuring scripts' Python reads run.h5 and fits with numpy (Debian's
# python3-h5py and python3-numpy, scripts/install-deps.sh): a python3 earlier
# on PATH without them (pyenv's or a virtualenv's) gives way to Debian's.
if ! python3 -c 'import numpy, h5py' 2>/dev/null && /usr/bin/python3 -c 'import numpy, h5py' 2>/dev/null; then
  python3() { /usr/bin/python3 "$@"; }
  export -f python3
fi
