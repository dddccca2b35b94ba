#!/usr/bin/env bash
# Stage II fidelity study (issue 16): deform each model with each spec at the defaults (CPU),
# then judge both outputs with `splatwarp eval` run separately, and print one Markdown row per
# run: Stage I and Stage II judged errors (opacity, colour, inside, outside), the Stage II / Stage I
# ratio, Gaussians, Stage II time, steps rejected, whether eval printed the report's numbers, and
# the deform run's CPU time (user + system) and peak RSS (GNU time).
#   bash scripts/fidelity-study.sh OUTDIR [MODEL...]   (SPECS="bend twist" to choose specs)
# Models default to the shared real models; extra deform flags go in DEFORM_FLAGS.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: fidelity-study.sh OUTDIR [MODEL...]}
shift
source scripts/study-models.sh
study_setup "$out" "$@"
specs=(${SPECS:-bend twist stretch squash rigid})
echo "| model | spec | Gaussians before -> after | Stage I opacity / colour (inside, outside) | Stage II opacity / colour (inside, outside) | ratio opacity / colour | Stage II s | rejected | eval = report | deform CPU s / peak MB |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for m in "${models[@]}"; do
  for s in "${specs[@]}"; do
    name="$(basename "${m%.*}")-$s"
    dir="$out/$name"
    # shellcheck disable=SC2086
    /usr/bin/time -o "$dir.time" -f "%U %S %M" "$bin" -q deform "$m" --spec "samples/specs/$s.json" -o "$dir" --device cpu ${DEFORM_FLAGS:-} > "$dir.log" 2>&1 ||
      { echo "| $name | failed: see $dir.log |"; continue; }
    for st in baseline deformed; do
      "$bin" -q eval --rest "$m" --spec "samples/specs/$s.json" --deformed "$dir/$st.ply" --json > "$dir/eval-$st.json"
    done
    python3 - "$dir" "$(basename "$m")" "$s" <<'PY'
import json, sys
d, model, spec = sys.argv[1:4]
user, system, rss_kb = open(f"{d}.time").read().split()[-3:]
r = json.load(open(f"{d}/report.json"))
e1, e2 = (json.load(open(f"{d}/eval-{s}.json")) for s in ("baseline", "deformed"))
f1, f2 = r["stage1"]["fieldError"], r["stage2"]["fieldError"]
same = "yes" if (e1 == f1 and e2 == f2) else "NO"
def cell(f):
    return (f"{f['opacity']:.4g} / {f['color']:.4g} ({f['inside']['opacity']:.4g}, "
            f"{f['outside']['opacity']:.3g})")
ratio = lambda k: f2[k] / f1[k] if f1[k] > 0 else float("nan")
s2 = r["stage2"]
moving = ("Stage II skipped (rigid)" if "skipped" in s2 else
          f"{r['input']['gaussians']} -> {s2['gaussians']} ({s2['movingGaussians']} moving)")
print(f"| {model} | {spec} | {moving} | {cell(f1)} | {cell(f2)} | "
      f"{ratio('opacity'):.3f} / {ratio('color'):.3f} | {r['timingsMs']['stage2'] / 1000:.1f} | "
      f"{s2.get('rejectedSteps', '-')} | {same} | {float(user) + float(system):.1f} / {int(rss_kb) / 1024:.0f} |")
PY
  done
done
