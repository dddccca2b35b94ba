#!/usr/bin/env bash
# Issue 14's engine figures, before and after, on one machine in one run:
#   bash scripts/engine-bench.sh OLD_BIN NEW_BIN [REPEATS]
# For each repeat, each binary in turn runs the demo (stripes + bend.json, 100 iterations), the
# donut bend45-y (40 cells, 20 iterations) and playbot-31k SH2 bend (40 cells, 60 iterations) with
# 2 threads on the CPU, no held-out evaluation, and prints Stage II's phases from report.json with
# the md5 of deformed.ply (the same bits are expected from both). Needs ../shared/data for the
# donut and playbot rows (skipped without it). Run on an idle machine: these are wall times.
set -euo pipefail
cd "$(dirname "$0")/.."
OLD=$1 NEW=$2 REPEATS=${3:-1}
DATA=${SPLATWARP_DATA:-../shared/data}/splats
OUT=$(mktemp -d /tmp/splatwarp-engine-bench.XXXXXX)
trap 'rm -rf "$OUT"' EXIT
"$NEW" sample stripes -o "$OUT/stripes.ply" >/dev/null 2>&1
run() { # label bin args...
    local label=$1 bin=$2
    shift 2
    "$bin" --threads 2 deform "$@" -o "$OUT/run" --device cpu --no-eval >/dev/null 2>&1
    python3 - "$label" "$OUT/run" <<'PY'
import hashlib, json, sys
label, d = sys.argv[1], sys.argv[2]
r = json.load(open(d + "/report.json"))
s = r["stage2"]; t = s["timingsMs"]
md5 = hashlib.md5(open(d + "/deformed.ply", "rb").read()).hexdigest()[:8]
print(f"{label:28s} stage2 {t['total']/1000:6.2f} s  setup {t['setup']/1000:5.2f}  coverage {t['coverage']/1000:5.2f} "
      f"({100*t['coverage']/t['total']:4.1f}%)  forward {t['forward']/1000:5.2f}  backward {t['backward']/1000:5.2f}  "
      f"update {t['update']/1000:5.2f}  rebuilds {s['coverageRebuilds']:2d}  {s['pairsPerSecond']/1e6:6.1f} M pairs/s  md5 {md5}")
PY
}
for rep in $(seq "$REPEATS"); do
    for which in old new; do
        bin=$OLD; [ "$which" = new ] && bin=$NEW
        run "demo $which" "$bin" "$OUT/stripes.ply" --spec samples/specs/bend.json
        if [ -f "$DATA/donut.ply" ]; then
            run "donut bend45-y $which" "$bin" "$DATA/donut.ply" --spec samples/specs/bend45-y.json --cells 40 --iterations 20
            run "playbot bend $which" "$bin" "$DATA/playbot-31k-sh2.ply" --spec samples/specs/bend.json --cells 40 --iterations 60
        fi
    done
done
