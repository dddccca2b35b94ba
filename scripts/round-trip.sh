#!/usr/bin/env bash
# The round trip splats -> to-vdb -> from-vdb (issue 12) for docs/lab/from-vdb.md: the volume at a
# lattice of CELLS cells, fitted back with as many Gaussians as the original (`--no-fit` and the
# fit), each judged against the original splats by `eval` twice: at the volume's lattice (`--lattice
# --cells CELLS`: the points and rest filter of the lattice the volume holds) and by the fixed judge
# (no filter: finer than the volume can hold). Prints one line per run. Long: run by hand, not in CI.
# Usage: bash scripts/round-trip.sh OUTDIR MODEL [CELLS] [extra from-vdb flags...]
set -euo pipefail
cd "$(dirname "$0")/.."
out=$1 model=$2 cells=${3:-64}
shift 2; shift || true
bin=${SPLATWARP:-build/tools/splatwarp}
mkdir -p "$out"
name=$(basename "${model%.*}")-$cells
spec=$out/identity.json
cat >"$spec" <<'EOF'
{"version": 1, "units": "bbox", "graph": {"nodes": 256, "k": 8, "seed": 0},
 "handles": [{"box": {"min": [-0.01, -0.01, -0.01], "max": [1.01, 1.01, 1.01]}}]}
EOF
count=$("$bin" info "$model" | awk '/^count:/ {print $2}')
cpu() { awk '{printf "%.1f", $1 + $2}' "$1"; }

/usr/bin/time -f "%U %S" -o "$out/$name.tovdb.time" \
    "$bin" -q to-vdb "$model" -o "$out/$name.vdb" --sh-grids --cells "$cells" --device cpu
echo "$name: $count Gaussians, $(stat -c %s "$out/$name.vdb") bytes of .vdb, to-vdb $(cpu "$out/$name.tovdb.time") s CPU"

for run in no-fit fit; do
    flags=(--gaussians "$count" --samples-per-voxel 1 --device cpu --eval-points 30000)
    [ "$run" = no-fit ] && flags+=(--no-fit)
    /usr/bin/time -f "%U %S" -o "$out/$name.$run.time" \
        "$bin" -q from-vdb "$out/$name.vdb" -o "$out/$name.$run.ply" "${flags[@]}" "$@" >/dev/null
    volume=$(python3 -c "import json,sys; h=json.load(open(sys.argv[1]))['heldOut']; print(h['fit' if 'fit' in h else 'noFit']['opacity'])" \
        "$out/$name.$run.report.json")
    lattice=$("$bin" -q eval --rest "$model" --deformed "$out/$name.$run.ply" --spec "$spec" --lattice --cells "$cells" --json)
    judge=$("$bin" -q eval --rest "$model" --deformed "$out/$name.$run.ply" --spec "$spec" --json)
    python3 - "$name" "$run" "$volume" "$lattice" "$judge" "$(cpu "$out/$name.$run.time")" <<'PY'
import json, sys
name, run, volume, lattice, judge, cpu = sys.argv[1:]
l, j = json.loads(lattice), json.loads(judge)
print(f"{name} {run}: vs volume {float(volume):.4f} | lattice judge opacity {l['opacity']:.4f} colour {l['color']:.4f}"
      f" | fixed judge opacity {j['opacity']:.4f} colour {j['color']:.4f} | PSNR {j['imagePsnr']['db']:.1f} dB"
      f" | from-vdb {cpu} s CPU")
PY
done
