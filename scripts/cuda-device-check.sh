#!/usr/bin/env bash
# Prepare the one device run of a lent GPU machine (docs/gpu.md, ../shared/docs/GPU.md): build
# the CLI and the CUDA tests (sm_90 SASS + PTX; the build dir is configured when it is not), pack
# them with their shared libraries and the donut and playbot models into .device/ (git-ignored,
# the one carried path), check it against the limits (<= 64 MiB carried, <= 8 result files) and
# print the device command (scripts/device-benchmarks.sh: tests, benches, deform runs, <= 450 s).
# usage: bash scripts/cuda-device-check.sh [--dry-run] [--rerun RESULTS_JSON] [BUILD_DIR]
#   --dry-run  also run the CPU half of the device run here, from the unpacked bundle
#   --rerun    the device command for only what failed in a previous run's results.json
set -euo pipefail
cd "$(dirname "$0")/.."
dry=0 rerun="" build=build
while [[ $# -gt 0 ]]; do
    case $1 in
        --dry-run) dry=1; shift ;;
        --rerun) rerun=$2; shift 2 ;;
        -*) echo "cuda-device-check: unknown option $1" >&2; exit 2 ;;
        *) build=$1; shift ;;
    esac
done
carryLimitMiB=64 resultLimit=8
results=(log.txt results.json gtest.json) # what scripts/device-benchmarks.sh writes to $OUT
t0=$SECONDS

if [[ ! -f $build/CMakeCache.txt ]]; then
    echo "cuda-device-check: configuring $build (CUDA on, default architectures 75-real;90)"
    cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DSPLATWARP_CUDA=ON >/dev/null
fi
# What nvcc generates (sm_90 SASS or compute_90 PTX runs on the H100/H200; CudaArch.ThisBuildRunsOnHopper checks it too).
grep -q 'arch=compute_90,code=[^ ]*\(sm_90\|compute_90\)' "$build/build.ninja" ||
    { echo "cuda-device-check: $build generates no sm_90 code (configure with -DCMAKE_CUDA_ARCHITECTURES=90)" >&2; exit 1; }
CCACHE_BASEDIR=${CCACHE_BASEDIR:-$(cd .. && pwd)} nice -n 10 cmake --build "$build" -j"${JOBS:-2}" --target splatwarp splatwarp_cuda_tests

mkdir -p .device/data
../shared/tools/device-bundle .device/bundle.tar.xz "$build/tools/splatwarp" "$build/tests/splatwarp_cuda_tests"
for f in donut.ply playbot-31k-sh2.ply; do
    cp -f "../shared/data/splats/$f" .device/data/ || { echo "cuda-device-check: ../shared/data/splats/$f missing" >&2; exit 1; }
done
bytes=$(du -sb .device | cut -f1)
mib=$(((bytes + 1048575) / 1048576))
echo "carried: .device, $mib MiB (limit $carryLimitMiB MiB)"
echo "results: ${#results[@]} files (${results[*]}; limit $resultLimit)"
((mib <= carryLimitMiB)) || { echo "cuda-device-check: .device is over the carry limit" >&2; exit 1; }
((${#results[@]} <= resultLimit)) || { echo "cuda-device-check: too many result files" >&2; exit 1; }

args=""
if [[ -n $rerun ]]; then
    args=$(python3 -c 'import json,sys; r=json.load(open(sys.argv[1]))["rerun"]; print("--steps %s --tests %s" % (r["steps"] or "none", "\x27" + r["tests"] + "\x27"))' "$rerun")
fi
cat <<CMD
Device run (run tool: carry [".device"], timeout_s 540):
mkdir -p /tmp/b && tar xJf .device/bundle.tar.xz -C /tmp/b && LD_LIBRARY_PATH=/tmp/b/lib bash scripts/device-benchmarks.sh ${args:+$args }/tmp/b .device/data
CMD
((dry)) || exit 0

# The CPU half, as the device will run it: from the unpacked bundle, into a fresh $OUT.
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/b" "$stage/out"
tar xJf .device/bundle.tar.xz -C "$stage/b"
t1=$SECONDS
rc=0
# No device time here, but 2 cores shared: 4x the timeouts, a larger budget.
OUT=$stage/out STEP_TIMEOUT_SCALE=4 LD_LIBRARY_PATH=$stage/b/lib \
    bash scripts/device-benchmarks.sh --cpu-only --budget 1800 "$stage/b" .device/data || rc=$?
rm -rf "$build/device-dry-run" && cp -r "$stage/out" "$build/device-dry-run" # for a look (not carried)
written=$(find "$stage/out" -type f | wc -l)
echo "dry run: CPU half rc $rc in $((SECONDS - t1)) s; $written files written: $(cd "$stage/out" && ls | tr '\n' ' ')(copied to $build/device-dry-run)"
python3 -m json.tool "$stage/out/results.json" >/dev/null || { echo "cuda-device-check: results.json is not JSON" >&2; exit 1; }
python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); print("dry run: steps", ", ".join("%s %s %ss" % (s["name"], s["status"], s.get("seconds", "-")) for s in r["steps"]))' "$stage/out/results.json"
((written <= resultLimit)) || { echo "cuda-device-check: $written result files (limit $resultLimit)" >&2; exit 1; }
echo "dry run: $mib MiB, ${#results[@]} files, $((SECONDS - t0)) s in all"
exit "$rc"
