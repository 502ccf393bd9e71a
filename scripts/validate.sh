#!/usr/bin/env bash
# Regenerates the results of docs/validation.md: runs each granular-flow
# validation (scripts/validate-<name>.sh: beverloo, drum, repose) and puts
# the stamped table it prints in place of the one the page holds (from its
# "Measured by `scripts/validate-<name>.sh`" line to the figure below it);
# the figures go to docs/figures/. About an hour and a quarter on two cores.
# The page is rewritten only once every validation has succeeded.
# Usage: scripts/validate.sh [--analyse] [NAME...]
#   --analyse  run nothing: read the runs already in out/validation/<name>/
#   NAME       only these validations (default: all three)
set -euo pipefail
cd "$(dirname "$0")/.."
analyse=0
names=()
for a in "$@"; do
  case $a in
    --analyse) analyse=1 ;;
    beverloo|drum|repose) names+=("$a") ;;
    *) echo "validate.sh: unknown argument '$a' (expected --analyse, beverloo, drum or repose)" >&2; exit 2 ;;
  esac
done
[ ${#names[@]} -gt 0 ] || names=(beverloo drum repose)
tables=$(mktemp -d)
trap 'rm -rf "$tables"' EXIT
for name in "${names[@]}"; do
  args=()
  [ $analyse -eq 1 ] && args=("out/validation/$name")
  echo "$name..." >&2
  "scripts/validate-$name.sh" "${args[@]}" > "$tables/$name.md"
done
/usr/bin/python3 - docs/validation.md "$tables" "${names[@]}" <<'PY'
import os, sys
page, tables, names = sys.argv[1], sys.argv[2], sys.argv[3:]
lines = open(page).read().split("\n")
for name in names:
    head = f"Measured by `scripts/validate-{name}.sh`"
    starts = [i for i, l in enumerate(lines) if l.startswith(head)]
    if len(starts) != 1:
        sys.exit(f"{page}: expected one line starting '{head}', found {len(starts)}")
    i = starts[0]
    ends = [j for j in range(i + 1, len(lines)) if lines[j].startswith("![")]
    if not ends:
        sys.exit(f"{page}:{i + 1}: no figure after the {name} table")
    new = open(os.path.join(tables, name + ".md")).read().strip().split("\n")
    lines[i:ends[0]] = new + [""]
tmp = page + ".new"
open(tmp, "w").write("\n".join(lines))
os.replace(tmp, page)
PY
echo "docs/validation.md: ${names[*]} regenerated" >&2
