#!/usr/bin/env bash
# Runs ON the lent GPU machine, from the repository root (scripts/cuda-device-check.sh prepares
# the bundle and prints the command): the CUDA tests, every `bench` and the Stage II deform runs
# (stripes, donut, playbot-31k SH2: 100 iterations on the GPU, 10 on the CPU), CPU and GPU in the
# same run, the GPU's steps first. Every step has its own timeout and the whole run a budget
# (default 450 s), so it ends inside the device time with whatever it measured (steps the
# budget leaves out are "skipped" and rerun later). Writes three files to $OUT (./device-out):
#   log.txt       every step's output, in order
#   results.json  per step: status, rc, seconds; failed steps and tests; tolerances seen
#                 ("[tolerance]" lines of the tests); bench output; each deform's report.json
#   gtest.json    the CUDA tests' own result file (per test: status, time, properties)
# usage: bash scripts/device-benchmarks.sh [--cpu-only] [--steps A,B] [--tests FILTER] [--budget S] BUNDLE_DIR DATA_DIR
#   --cpu-only  the CPU half only (the dry run on a machine without a GPU)
#   --steps     only these steps (a rerun of the failed ones: results.json "rerun")
#   --tests     gtest filter for the cuda-tests step
#   STEP_TIMEOUT_SCALE  multiplies every step's timeout (the dry run on 2 cores: 4)
set -uo pipefail
cpuOnly=0 steps="" tests="*" budget=450
while [[ $# -gt 2 ]]; do
    case $1 in
        --cpu-only) cpuOnly=1; shift ;;
        --steps) steps=$2; shift 2 ;;
        --tests) tests=$2; shift 2 ;;
        --budget) budget=$2; shift 2 ;;
        *) echo "device-benchmarks: unknown option $1" >&2; exit 2 ;;
    esac
done
[[ $# -eq 2 ]] || { sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
bin=$1/bin
data=$2
out=${OUT:-device-out}
mkdir -p "$out"
out=$(cd "$out" && pwd)
work=$(mktemp -d)
log=$out/log.txt
: >"$log"
start=$SECONDS
entries=() failed=() reports=() benches=()

# The text of a file as a JSON string (quotes, backslashes and control bytes escaped).
json_string() {
    printf '"'
    LC_ALL=C sed -e 's/\\/\\\\/g' -e 's/"/\\"/g' -e 's/\t/\\t/g' -e 's/\r//g' "$1" | LC_ALL=C tr -d '\000-\010\013-\037' |
        awk 'NR > 1 { printf "\\n" } { printf "%s", $0 }'
    printf '"'
}

wanted() { [[ -z $steps || ",$steps," == *",$1,"* ]]; }

# step NAME TIMEOUT COMMAND: run the command (bash, with the functions below) with the smaller
# of its timeout and the budget left.
step() {
    local name=$1 limit=$2 command=$3
    wanted "$name" || return 0
    local left=$((budget - (SECONDS - start)))
    if ((left < 5)); then
        entries+=("{\"name\":\"$name\",\"status\":\"skipped\",\"reason\":\"budget spent\"}")
        failed+=("$name")
        return 0
    fi
    limit=$((limit * ${STEP_TIMEOUT_SCALE:-1}))
    ((limit > left)) && limit=$left
    echo "=== $name (timeout ${limit}s): $command" >>"$log"
    local t0=$SECONDS rc status
    timeout --kill-after=5 "$limit" bash -c "$command" >"$work/$name.txt" 2>&1
    rc=$?
    cat "$work/$name.txt" >>"$log"
    status=ok
    ((rc == 124 || rc == 137)) && status=timeout
    ((rc != 0 && rc != 124 && rc != 137)) && status=failed
    [[ $status != ok ]] && failed+=("$name")
    entries+=("{\"name\":\"$name\",\"status\":\"$status\",\"rc\":$rc,\"seconds\":$((SECONDS - t0)),\"timeout\":$limit}")
    echo "=== $name: $status (rc $rc, $((SECONDS - t0)) s)" >>"$log"
}

benches() { # DEVICE: every bench, one after another
    local b
    for b in stage1 to-vdb features render 'stage2 --iterations 20'; do
        # shellcheck disable=SC2086  # $b holds a subcommand and its flags
        "$bin/splatwarp" bench $b --device "$1" || return 1
    done
}

deform() { # NAME MODEL SPEC DEVICE ITERATIONS
    "$bin/splatwarp" deform "$2" --spec "$3" -o "$work/$1-$4" --device "$4" --iterations "$5" --no-eval
}
export -f benches deform
export bin work

gpu=1
((cpuOnly)) && gpu=0
step device-info 20 'nvidia-smi -L || true; nvidia-smi --query-gpu=name,compute_cap,memory.total,driver_version --format=csv || true; "$bin/splatwarp" --version'
step cuda-tests 150 "\"\$bin/splatwarp_cuda_tests\" --gtest_filter='$tests' --gtest_output=json:'$out/gtest.json'"
"$bin/splatwarp" sample stripes -o "$work/stripes.ply" >/dev/null 2>&1
models=("stripes:$work/stripes.ply:samples/specs/bend.json" "donut:$data/donut.ply:samples/specs/bend45-y.json"
        "playbot:$data/playbot-31k-sh2.ply:samples/specs/bend.json")
# The GPU's steps first: when the budget runs out, the CPU comparison is what is left out.
for d in cuda cpu; do
    [[ $d == cuda ]] && ((!gpu)) && continue
    n=100 limit=45
    [[ $d == cpu ]] && n=10 limit=60
    step "bench-$d" 60 "benches $d"
    [[ -f $work/bench-$d.txt ]] && benches+=("\"$d\":$(json_string "$work/bench-$d.txt")")
    for m in "${models[@]}"; do
        IFS=: read -r name model spec <<<"$m"
        step "deform-$name-$d" "$limit" "deform '$name' '$model' '$spec' $d $n"
        r=$work/$name-$d/report.json
        [[ -s $r ]] && reports+=("\"deform-$name-$d\":$(tr -d '\n' <"$r")")
    done
done

# Tolerances the tests saw: "[tolerance] NAME seen X allowed Y".
tol=$(grep -h '^\[tolerance\]' "$log" | awk 'function num(v) { return v ~ /^[-+]?[0-9.]+([eE][-+]?[0-9]+)?$/ ? v : "\"" v "\"" }
    { printf "%s{\"name\":\"%s\",\"seen\":%s,\"allowed\":%s}", (NR > 1 ? "," : ""), $2, num($4), num($6) }')
failedTests=$(grep -h '^\[  FAILED  \] [A-Za-z0-9_]*\.[A-Za-z0-9_/]*' "$work/cuda-tests.txt" 2>/dev/null | awk '{print $4}' | sort -u | paste -sd: -)
join() { local IFS=,; echo "$*"; }
names=()
for f in "${failed[@]}"; do names+=("\"$f\""); done
{
    printf '{"gpu":%s,"budgetSeconds":%s,"elapsedSeconds":%s,' "$([[ $gpu == 1 ]] && echo true || echo false)" "$budget" "$((SECONDS - start))"
    printf '"steps":[%s],"failed":[%s],"failedTests":"%s",' "$(join "${entries[@]}")" "$(join "${names[@]}")" "$failedTests"
    printf '"rerun":{"steps":"%s","tests":"%s"},' "$(IFS=,; echo "${failed[*]}")" "${failedTests:-*}"
    printf '"tolerances":[%s],"bench":{%s},"reports":{%s}}\n' "$tol" "$(join "${benches[@]}")" "$(join "${reports[@]}")"
} >"$out/results.json"
rm -rf "$work"
echo "device-benchmarks: $((SECONDS - start)) s, ${#failed[@]} failed step(s)${failed[*]:+: ${failed[*]}}; results in $out"
[[ ${#failed[@]} -eq 0 ]]
