#!/usr/bin/env bash
# Submits a job template from the repository root, making its log directory
# first: slurmd opens a job's --output file before the script runs, and a
# missing out/ (it is not in git) fails the job at launch.
# Usage: jobs/submit.sh [SBATCH OPTIONS] jobs/TEMPLATE.sbatch [ARGS...]
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p out
exec sbatch "$@"
