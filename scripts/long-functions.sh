#!/usr/bin/env bash
# List the functions over N lines (default 80) outside tests, longest first: the house rule is
# that a body that long usually hides a class. Uses Universal Ctags (Debian: universal-ctags).
# Usage: bash scripts/long-functions.sh [N]
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:-80}
command -v ctags >/dev/null || { echo "long-functions: needs ctags (apt-get install universal-ctags)" >&2; exit 2; }
git ls-files '*.cpp' '*.h' '*.cu' '*.cuh' | grep -v '^tests/' |
  xargs ctags --fields=+ne -o - --kinds-C++=fp --language-force=C++ 2>/dev/null |
  awk -F'\t' -v n="$n" '{
      line = 0; end = 0
      for (i = 4; i <= NF; i++) { if ($i ~ /^line:/) line = substr($i, 6); if ($i ~ /^end:/) end = substr($i, 5) }
      if (end - line + 1 > n) printf "%4d %s:%d %s\n", end - line + 1, $2, line, $1
  }' | sort -rn
