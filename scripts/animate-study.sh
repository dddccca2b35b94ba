#!/usr/bin/env bash
# Animation study for the README: 24 frames of the stripes bend (samples/specs/bend-24.json) by one
# `animate` run against 24 separate `deform` runs of the same frame specs; CPU time (user+sys) of
# each, and a byte comparison of every frame. Usage: scripts/animate-study.sh [ITERATIONS] [OUTDIR]
set -euo pipefail
cd "$(dirname "$0")/.."
IT=${1:-10}
OUT=${2:-out/animate-study}
B=build/tools/splatwarp
rm -rf "$OUT" && mkdir -p "$OUT"
$B -q sample stripes -o "$OUT/stripes.ply"
$B -q animate --spec samples/specs/bend-24.json -o "$OUT/anim" --specs-only >/dev/null
cpu() { /usr/bin/time -f "%U %S %e" -o "$1" "${@:2}"; }
cpu "$OUT/animate.time" $B -q animate "$OUT/stripes.ply" --spec samples/specs/bend-24.json -o "$OUT/anim" --iterations "$IT" >/dev/null
: > "$OUT/deform.times"
for f in $(seq 0 23); do
  n=$(printf %04d "$f")
  cpu "$OUT/t" $B -q deform "$OUT/stripes.ply" --spec "$OUT/anim/specs/spec.$n.json" -o "$OUT/d$n" --iterations "$IT" >/dev/null
  cat "$OUT/t" >> "$OUT/deform.times"
  cmp -s "$OUT/d$n/deformed.ply" "$OUT/anim/frames/deformed.$n.ply" || echo "frame $f differs from deform" | tee -a "$OUT/mismatch"
done
read -r au as aw < "$OUT/animate.time"
awk -v au="$au" -v as="$as" -v aw="$aw" -v it="$IT" '{u+=$1; s+=$2; w+=$3}
  END {a=au+as; d=u+s; printf "iterations %d: animate 24 frames %.1f s CPU (%.1f s wall), %.2f s CPU/frame; 24 deform runs %.1f s CPU (%.1f s wall), %.2f s CPU/frame; speed-up %.2fx\n", it, a, aw, a/24, d, w, d/24, d/a}' "$OUT/deform.times" | tee "$OUT/summary.txt"
[ ! -e "$OUT/mismatch" ] && echo "all 24 frames byte-identical to deform" | tee -a "$OUT/summary.txt"
