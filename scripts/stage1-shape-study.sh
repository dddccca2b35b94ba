#!/usr/bin/env bash
# Stage I shape study (issue 16): judge Stage I alone with each shape rule (`deform --stage1-only
# --stage1-shape polar|affine`, then `splatwarp eval` on baseline.ply) and print one Markdown row
# per model and spec: opacity / colour error of each and affine / polar.
#   bash scripts/stage1-shape-study.sh OUTDIR [MODEL...]   (SPECS="bend twist" to choose specs)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: stage1-shape-study.sh OUTDIR [MODEL...]}
shift
source scripts/study-models.sh
study_setup "$out" "$@"
specs=(${SPECS:-bend twist stretch squash})
echo "| model | spec | polar (the paper) opacity / colour | affine opacity / colour | affine / polar |"
echo "|---|---|---|---|---|"
for m in "${models[@]}"; do
  for s in "${specs[@]}"; do
    name="$(basename "${m%.*}")-$s"
    row="| $(basename "$m") | $s |"
    declare -A err=()
    for shape in polar affine; do
      dir="$out/$name-$shape"
      if "$bin" -q deform "$m" --spec "samples/specs/$s.json" -o "$dir" --device cpu --stage1-only --no-eval \
           --stage1-shape "$shape" > "$dir.log" 2>&1; then
        err[$shape]=$("$bin" -q eval --rest "$m" --spec "samples/specs/$s.json" --deformed "$dir/baseline.ply" --json |
          python3 -c "import json,sys; e=json.load(sys.stdin); print(e['opacity'], e['color'])")
      else
        err[$shape]="failed failed"
      fi
    done
    python3 - "$row" ${err[polar]} ${err[affine]} <<'PY'
import sys
row, po, pc, ao, ac = sys.argv[1:6]
if "failed" in (po, ao):
    print(f"{row} {po} / {pc} | {ao} / {ac} | Stage I failed (see the logs) |")
else:
    print(f"{row} {float(po):.4g} / {float(pc):.4g} | {float(ao):.4g} / {float(ac):.4g} | "
          f"{float(ao) / float(po):.3f} / {float(ac) / float(pc):.3f} |")
PY
  done
done
