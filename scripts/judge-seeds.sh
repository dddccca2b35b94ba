#!/usr/bin/env bash
# The fixed judge over several of its seeds: judges DIR/baseline.ply and DIR/deformed.ply (a deform
# output folder) with `splatwarp eval --seed k`, k = 1..K (default 16), and prints the ratio of the
# summed Stage II and Stage I opacity errors (the same seeds for both), seed 1's ratio (what the
# judge prints) and the standard deviation of the per-seed ratios. One seed's 100k points are few
# inside a sparse capture (train-1000: ~6,000); compare levers on this mean (docs/lab/fidelity-study.md).
#   bash scripts/judge-seeds.sh MODEL SPEC DIR [K]      (SPLATWARP_BIN picks the binary)
set -euo pipefail
cd "$(dirname "$0")/.."
model=${1:?usage: judge-seeds.sh MODEL SPEC DIR [K]}
spec=${2:?usage: judge-seeds.sh MODEL SPEC DIR [K]}
dir=${3:?usage: judge-seeds.sh MODEL SPEC DIR [K]}
k=${4:-16}
bin=${SPLATWARP_BIN:-build/tools/splatwarp}
for seed in $(seq 1 "$k"); do
  for st in baseline deformed; do
    "$bin" -q eval --rest "$model" --spec "$spec" --deformed "$dir/$st.ply" --seed "$seed" --json > "$dir/judge-$st-$seed.json"
  done
done
python3 - "$dir" "$k" <<'PY'
import json, statistics, sys
d, k = sys.argv[1], int(sys.argv[2])
err = lambda st, s: json.load(open(f"{d}/judge-{st}-{s}.json"))["opacity"]
a = [err("baseline", s) for s in range(1, k + 1)]
b = [err("deformed", s) for s in range(1, k + 1)]
r = [y / x for x, y in zip(a, b)]
print(f"{d}: Stage II / Stage I opacity, mean of {k} seeds {sum(b) / sum(a):.4f}, seed 1 {r[0]:.4f}, "
      f"sd between seeds {statistics.pstdev(r):.4f}")
PY
