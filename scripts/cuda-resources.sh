#!/usr/bin/env bash
# Registers, stack/spill bytes and shared memory per kernel of one CUDA source, for sm_90, as ptxas
# reports them (no GPU needed): the build's own nvcc command for SOURCE with one target (sm_90) and
# -Xptxas -v. The occupancy these give is checked on a GPU by StageTwoCuda.EveryKernelReachesAQuarter...
# usage: bash scripts/cuda-resources.sh [BUILD_DIR] [SOURCE]   (defaults: build-cuda kernels/StageTwoCuda.cu)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-cuda}
src=${2:-kernels/StageTwoCuda.cu}
obj="kernels/CMakeFiles/splatwarp_kernels.dir/$(basename "$src").o"
cmd=$(ninja -C "$build" -t commands "$obj" | tail -1)
[ -n "$cmd" ] || { echo "no compile command for $obj in $build (configure it with -DSPLATWARP_CUDA=ON)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# One sm_90 target, ptxas verbose, object into the temporary folder.
cmd=$(sed -E 's/--generate-code=[^ ]+//g; s/ -o [^ ]+/ -o '"${tmp//\//\\/}"'\/k.o/' <<<"$cmd")
(cd "$build" && eval "$cmd --generate-code=arch=compute_90,code=[sm_90] -Xptxas -v") 2>"$tmp/ptxas.txt" >/dev/null
python3 - "$tmp/ptxas.txt" <<'PY' | c++filt | sed -E 's/^(void )?splatwarp::cuda::\(anonymous namespace\):://; s/\((unsigned long|splatwarp)[^|]*\)//'
import re, sys
name, spill = None, ""
for line in open(sys.argv[1]):
    m = re.search(r"Compiling entry function '(\S+)'", line)
    if m:
        name, spill = m.group(1), ""
        continue
    m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", line)
    if m:
        spill = "stack %s, spill stores %s, loads %s" % m.groups()
        continue
    m = re.search(r"Used (\d+) registers(.*)", line)
    if m and name and "splatwarp" in name and "cub" not in name.split("splatwarp")[0]:
        smem = re.search(r"(\d+) bytes smem", line)
        print("%s | %s registers | %s | %s B shared" % (name, m.group(1), spill, smem.group(1) if smem else "0"))
        name = None
PY
