#!/usr/bin/env bash
# from-vdb measurements for docs/lab/from-vdb.md: held-out density error of the baseline (--no-fit) and
# the fit, wall and CPU time, at several Gaussian budgets. Long: run by hand, not in CI.
# Usage: bash scripts/from-vdb-study.sh [OUTDIR] [extra from-vdb flags...]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/from-vdb-study}; shift || true
bin=build/tools/splatwarp
data=../shared/data
mkdir -p "$out"

# run NAME INPUT [flags...]: one fit, one line "NAME gaussians no-fit fit wall_s cpuSeconds ply_bytes".
run() {
    local name=$1 input=$2; shift 2
    /usr/bin/time -v "$bin" -q from-vdb "$input" -o "$out/$name.ply" "$@" >/dev/null 2>"$out/$name.time"
    python3 - "$out/$name" <<'PY'
import json, os, re, sys
base = sys.argv[1]
r = json.load(open(base + ".report.json"))
t = open(base + ".time").read()
wall = re.search(r"Elapsed \(wall clock\) time.*: (.*)", t).group(1)
user = float(re.search(r"User time \(seconds\): (.*)", t).group(1))
sys_ = float(re.search(r"System time \(seconds\): (.*)", t).group(1))
h = r["heldOut"]
fit = h.get("fit", {}).get("opacity", float("nan"))
print(f"{os.path.basename(base)} gaussians={r['gaussians']['final']} no-fit={h['noFit']['opacity']:.4f} "
      f"fit={fit:.4f} wall={wall} cpu={user + sys_:.1f}s ply={os.path.getsize(base + '.ply')}")
PY
}

cloud=$data/volumes/wdas_cloud_sixteenth.vdb
smoke=$data/volumes/smoke.vdb
voxels_cloud=415642
for per in 64 16 8 2 1; do
    run "cloud-1per$per" "$cloud" --gaussians $((voxels_cloud / per)) "$@"
done
run "smoke-1per8" "$smoke" "$@"
ls -l "$cloud" "$smoke"
