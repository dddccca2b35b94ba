#!/usr/bin/env bash
# Runs ON the lent GPU machine (see scripts/cuda-device-check.sh): the CUDA parity tests, then every
# `bench` and the issue's Stage II benchmarks (stripes-bend, donut-bend, playbot-31k SH2: 100
# iterations on the GPU, 10 on the CPU for the per-iteration comparison), all in one run so CPU and
# GPU numbers come from the same machine. Logs go to $OUT (or ./device-out).
# usage: bash scripts/device-benchmarks.sh BUNDLE_DIR DATA_DIR
set -uo pipefail
bin=$1/bin
data=$2
out=${OUT:-device-out}
mkdir -p "$out" /tmp/dv
nvidia-smi -L 2>&1 | tee "$out/device.txt"
"$bin/splatwarp" --version 2>&1 | tee -a "$out/device.txt"
"$bin/splatwarp_cuda_tests" 2>&1 | tee "$out/cuda_tests.txt" | tail -40
for d in cuda cpu; do
    for b in stage1 to-vdb features render 'stage2 --iterations 20'; do
        # shellcheck disable=SC2086  # $b holds a subcommand and its flags
        "$bin/splatwarp" bench $b --device $d 2>&1
    done | tee "$out/bench_$d.txt"
done
"$bin/splatwarp" sample stripes -o /tmp/dv/stripes.ply >/dev/null
run() { # name model spec device iterations
    "$bin/splatwarp" deform "$2" --spec "$3" -o "/tmp/dv/$1-$4" --device "$4" --iterations "$5" --no-eval >"$out/deform_$1_$4.log" 2>&1
    echo "$1 $4 $5 it: rc=$? $(python3 -c "import json,sys; r=json.load(open(sys.argv[1])); s=r['stage2']; t=r['timingsMs']; print('stage2', s.get('device'), 'pairs/s %.3g' % s['pairsPerSecond'], 'gpuPeakMiB %.0f' % (s.get('gpuPeakBytes',0)/2**20), 'stage2 ms', {k: round(v) for k, v in s['timingsMs'].items()}, 'job ms', {k: round(v) for k, v in t.items()})" "/tmp/dv/$1-$4/report.json" 2>&1)" | tee -a "$out/stage2.txt"
}
for d in cuda cpu; do
    n=100; [ $d = cpu ] && n=10
    run stripes-bend /tmp/dv/stripes.ply samples/specs/bend.json $d $n
    run donut-bend "$data/donut.ply" samples/specs/bend45-y.json $d $n
    run playbot-bend "$data/playbot-31k-sh2.ply" samples/specs/bend.json $d $n
done
