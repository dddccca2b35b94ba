#!/usr/bin/env bash
# Build the libFuzzer targets (tests/fuzz; clang, ASan + UBSan) into build-fuzz and run each for
# SECONDS (default 30) from its seed corpus, or until RUNS executions when given; print
# executions and crashes per target. Usage: scripts/fuzz.sh [SECONDS] [RUNS]
# Exit 1 when any target found a crash. Findings go to build-fuzz/runs/<target>/crashes/.
set -euo pipefail
cd "$(dirname "$0")/.."
SECS="${1:-30}"
RUNS="${2:--1}"
TARGETS=(ply_header ply compressed_ply splat spz spz4 gltf vdb_points spec cameras manifest job_list vdb_meta recipe sog vdb_layout picture_size)
start=$(date +%s)
cmake -S tests/fuzz -B build-fuzz -G Ninja -DCMAKE_CXX_COMPILER=clang++ >/dev/null
cmake --build build-fuzz -j"$(nproc)"
echo "fuzz: build $(( $(date +%s) - start )) s"
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
total_crashes=0
printf '%-16s %12s %8s %8s\n' target executions crashes seconds
for t in "${TARGETS[@]}"; do
  run="build-fuzz/runs/$t"
  # FUZZ_KEEP_CORPUS=1 continues from the previous run's corpus (long runs in several sessions).
  [ "${FUZZ_KEEP_CORPUS:-0}" = 1 ] || rm -rf "$run"
  rm -rf "$run/crashes" && mkdir -p "$run/corpus" "$run/crashes"
  t0=$(date +%s)
  # The first corpus dir receives new inputs, the committed seeds stay untouched; a target stops
  # at its first crash.
  "build-fuzz/fuzz_$t" -max_total_time="$SECS" -runs="$RUNS" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$run/crashes/" "$run/corpus" "tests/fuzz/corpus/$t" >"$run/log" 2>&1 || true
  execs=$(awk '/stat::number_of_executed_units/ {print $2}' "$run/log")
  crashes=$(find "$run/crashes" -type f | wc -l)
  total_crashes=$((total_crashes + crashes))
  printf '%-16s %12s %8d %8d\n' "$t" "${execs:-?}" "$crashes" $(( $(date +%s) - t0 ))
  if [ "$crashes" -gt 0 ]; then grep -m1 -A12 "ERROR\|runtime error\|terminate\|deadly" "$run/log" || tail -20 "$run/log"; fi
done
echo "fuzz: total $(( $(date +%s) - start )) s, $total_crashes crashes"
[ "$total_crashes" -eq 0 ]
