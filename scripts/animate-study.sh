#!/usr/bin/env bash
# Animation study (docs/lab/animation-study.md): frames A-B of the stripes bend
# (samples/specs/bend-24.json) by one `animate` run against separate `deform` runs of the same frame
# specs (CPU time, user+sys, one thread each; a byte comparison of every frame), and optionally an
# `animate` run with extra flags (e.g. --warm-start): its CPU time, judged field errors and
# frame-to-frame change. The three runs go in parallel (the machine is shared: compare CPU, not wall).
# Usage: scripts/animate-study.sh [ITERATIONS] [OUTDIR] [A-B] [FLAGS OF THE THIRD RUN...]
set -euo pipefail
cd "$(dirname "$0")/.."
IT=${1:-100}
OUT=${2:-out/animate-study}
RANGE=${3:-0-23}
shift $(( $# < 3 ? $# : 3 ))
OTHER=("$@")
B=${SPLATWARP:-build/tools/splatwarp}
A=${RANGE%-*} Z=${RANGE#*-}
rm -rf "$OUT" && mkdir -p "$OUT"
$B -q sample stripes -o "$OUT/stripes.ply"
$B -q animate --spec samples/specs/bend-24.json -o "$OUT/specs" --specs-only >/dev/null
cpu() { /usr/bin/time -f "%U %S %e" -o "$1" "${@:2}"; }
run_animate() { # NAME FLAGS...
  cpu "$OUT/$1.time" $B -q --threads 1 animate "$OUT/stripes.ply" --spec samples/specs/bend-24.json -o "$OUT/$1" \
    --iterations "$IT" --frames "$RANGE" "${@:2}" >/dev/null
}
run_deforms() {
  : > "$OUT/deform.times"
  for f in $(seq "$A" "$Z"); do
    n=$(printf %04d "$f")
    cpu "$OUT/t" $B -q --threads 1 deform "$OUT/stripes.ply" --spec "$OUT/specs/specs/spec.$n.json" -o "$OUT/d$n" \
      --iterations "$IT" >/dev/null
    cat "$OUT/t" >> "$OUT/deform.times"
  done
}
run_animate anim &
run_deforms &
[ ${#OTHER[@]} -gt 0 ] && run_animate other "${OTHER[@]}" &
wait
N=$(( Z - A + 1 ))
for f in $(seq "$A" "$Z"); do
  n=$(printf %04d "$f")
  cmp -s "$OUT/d$n/deformed.ply" "$OUT/anim/frames/deformed.$n.ply" || echo "frame $f differs from deform" | tee -a "$OUT/mismatch"
done
read -r au as aw < "$OUT/anim.time"
awk -v au="$au" -v as="$as" -v aw="$aw" -v it="$IT" -v n="$N" -v r="$RANGE" '{u+=$1; s+=$2; w+=$3}
  END {a=au+as; d=u+s; printf "iterations %d, frames %s: animate %.1f s CPU (%.1f s wall), %.2f s CPU/frame; %d deform runs %.1f s CPU (%.1f s wall), %.2f s CPU/frame; speed-up %.2fx\n", it, r, a, aw, a/n, n, d, w, d/n, d/a}' \
  "$OUT/deform.times" | tee "$OUT/summary.txt"
[ ! -e "$OUT/mismatch" ] && echo "all $N frames byte-identical to deform" | tee -a "$OUT/summary.txt"
python3 scripts/animate-compare.py "$OUT" "$A" "$Z" | tee -a "$OUT/summary.txt"
