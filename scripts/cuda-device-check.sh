#!/usr/bin/env bash
# Pack the CLI and the CUDA test binary for a lent GPU machine (see ../shared/docs/GPU.md) and
# print the device command that runs the CUDA parity tests and every `bench` on both devices.
# The default build already holds sm_90 code (CMAKE_CUDA_ARCHITECTURES "75-real;90").
# usage: bash scripts/cuda-device-check.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
cmake --build "$build" -j2 --target splatwarp splatwarp_cuda_tests
../shared/tools/device-bundle .device/bundle.tar.xz "$build/tools/splatwarp" "$build/tests/splatwarp_cuda_tests"
cat <<'CMD'
Device run (carry: [".device"]):
mkdir -p /tmp/b && tar xJf .device/bundle.tar.xz -C /tmp/b && export LD_LIBRARY_PATH=/tmp/b/lib && nvidia-smi -L && /tmp/b/bin/splatwarp_cuda_tests 2>&1 | tee $OUT/cuda_tests.txt | tail -60; for d in cpu cuda; do for b in stage1 to-vdb features render 'stage2 --iterations 20'; do /tmp/b/bin/splatwarp bench $b --device $d 2>&1; done | tee $OUT/bench_$d.txt; done
CMD
