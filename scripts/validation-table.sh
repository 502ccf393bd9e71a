#!/usr/bin/env bash
# The validation table of contact mechanics where faces, edges and corners
# touch (docs/tables.md, "Validation", written by scripts/tables.sh): runs
# dem's contact_mechanics tests, which assert each limit, and prints the rows
# they report (case, limit, measured) as a markdown table, stamped.
# Usage: scripts/validation-table.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
out=$(mktemp)
trap 'rm -f "$out"' EXIT
cargo test --release -p dem --test contact_mechanics -- --nocapture --test-threads 1 >"$out" 2>/dev/null
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
echo "Measured by \`scripts/validation-table.sh\` on $cpu ($(nproc) cores), commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d): every row passed its test (\`cargo test --release -p dem --test contact_mechanics\`)."
echo
echo "| case | limit (the measure is at most) | measured |"
echo "|---|---|---|"
grep -o 'validation | .*' "$out" | sed 's/^validation //' | sort
