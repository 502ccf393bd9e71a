#!/usr/bin/env bash
# Submits a job template from the repository root, whatever the directory
# it is called from (a plain `sbatch jobs/TEMPLATE.sbatch` from the root does
# the same: out/, where the logs go, is kept in git).
# Usage: jobs/submit.sh [SBATCH OPTIONS] jobs/TEMPLATE.sbatch [ARGS...]
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p out
exec sbatch "$@"
