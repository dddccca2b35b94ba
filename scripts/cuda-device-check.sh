#!/usr/bin/env bash
# Pack the CLI and the CUDA test binary for a lent GPU machine (see ../shared/docs/GPU.md) and
# print the device command (scripts/device-benchmarks.sh: every test of splatwarp_cuda_tests -- parity,
# kernel occupancy, counts past 2^31 and 2^32 (up to ~78 GB of GPU memory) --, every bench and the
# Stage II benchmarks, CPU and GPU in the same run). The donut and playbot models travel in .device/data.
# The default build already holds sm_90 code (CMAKE_CUDA_ARCHITECTURES "75-real;90").
# usage: bash scripts/cuda-device-check.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
cmake --build "$build" -j2 --target splatwarp splatwarp_cuda_tests
../shared/tools/device-bundle .device/bundle.tar.xz "$build/tools/splatwarp" "$build/tests/splatwarp_cuda_tests"
mkdir -p .device/data
for f in donut.ply playbot-31k-sh2.ply; do cp -f "../shared/data/splats/$f" .device/data/ 2>/dev/null || echo "note: ../shared/data/splats/$f missing"; done
cat <<'CMD'
Device run (carry: [".device"]):
mkdir -p /tmp/b && tar xJf .device/bundle.tar.xz -C /tmp/b && export LD_LIBRARY_PATH=/tmp/b/lib && bash scripts/device-benchmarks.sh /tmp/b .device/data
CMD
