#!/usr/bin/env bash
# The real Slurm test (ctest: SlurmArray.*): installs Debian's munge + slurm-wlm when missing,
# starts munged (unless one answers), slurmctld and slurmd on local ports with its own slurm.conf,
# submits samples/slurm/animate.sbatch as a 2-task array over 6 frames of a small stripes model,
# waits (bounded), merges, and compares every frame with a one-process run. Stops every daemon
# it started. Exit 0 pass, 1 mismatch or failure, 77 skipped (not root, no packages).
# Usage: run-slurm-test.sh SPLATWARP_BINARY SOURCE_DIR
set -uo pipefail
B=$(readlink -f "$1")
SRC=$(readlink -f "$2")
skip() { echo "SKIP: $*"; exit 77; }
fail() { echo "FAIL: $*"; for f in "$T"/*.log "$T"/slurm-*.out; do [ -f "$f" ] && { echo "== $f"; tail -n 20 "$f"; }; done; exit 1; }
[ "$(id -u)" -eq 0 ] || skip "not root: cannot install or start munge and Slurm"

if ! command -v sbatch >/dev/null || ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null ||
   ! command -v munged >/dev/null; then
  echo "installing munge + slurm-wlm (Debian packages)"
  export DEBIAN_FRONTEND=noninteractive
  { timeout 600 apt-get install -y -qq --no-install-recommends munge slurm-wlm ||
    { timeout 300 apt-get update -qq && timeout 600 apt-get install -y -qq --no-install-recommends munge slurm-wlm; }; } \
    >/tmp/splatwarp-slurm-install.log 2>&1 || skip "cannot install munge + slurm-wlm (see /tmp/splatwarp-slurm-install.log)"
fi

T=$(mktemp -d /tmp/splatwarp-slurm.XXXXXX)
chmod 755 "$T"
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null; done
  for _ in 1 2 3 4 5; do
    alive=0; for p in "${PIDS[@]}"; do kill -0 "$p" 2>/dev/null && alive=1; done
    [ $alive -eq 0 ] && break; sleep 1
  done
  for p in "${PIDS[@]}"; do kill -9 "$p" 2>/dev/null; done
  rm -rf "$T"
}
trap cleanup EXIT

# munge: reuse a running munged, else start one as user munge (Debian's layout, no systemd).
if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
  mkdir -p /run/munge /var/log/munge /var/lib/munge
  chown munge:munge /run/munge /var/log/munge /var/lib/munge && chmod 755 /run/munge
  if [ ! -s /etc/munge/munge.key ]; then
    (mungekey --create 2>/dev/null || dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 2>/dev/null)
    chown munge:munge /etc/munge/munge.key && chmod 400 /etc/munge/munge.key
  fi
  runuser -u munge -- munged || skip "cannot start munged"
  for _ in $(seq 20); do [ -s /run/munge/munged.pid ] && break; sleep 0.2; done
  PIDS+=("$(cat /run/munge/munged.pid)")
  munge -n | unmunge >/dev/null || fail "munge does not answer"
fi

HOST=$(hostname -s)
PORT=$((20000 + RANDOM % 20000))
mkdir -p "$T/state" "$T/spool"
cat > "$T/slurm.conf" <<CONF
ClusterName=splatwarptest
SlurmctldHost=$HOST(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
AuthType=auth/munge
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
SlurmctldLogFile=$T/slurmctld.log
SlurmdLogFile=$T/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=splatwarp Nodes=$HOST Default=YES MaxTime=10 State=UP
CONF
export SLURM_CONF=$T/slurm.conf
slurmctld -D -f "$SLURM_CONF" >"$T/slurmctld.out.log" 2>&1 & PIDS+=($!)
slurmd -D -f "$SLURM_CONF" -N "$HOST" >"$T/slurmd.out.log" 2>&1 & PIDS+=($!)
for _ in $(seq 60); do
  [ "$(sinfo -h -o %T 2>/dev/null | head -n1)" = "idle" ] && break; sleep 0.5
done
[ "$(sinfo -h -o %T 2>/dev/null | head -n1)" = "idle" ] || fail "the Slurm node did not come up"

# 6 frames of a small stripes bar, few iterations.
"$B" -q sample stripes --count 3000 -o "$T/stripes.ply" >/dev/null || fail "sample"
sed 's/"frames": 24/"frames": 6/' "$SRC/samples/specs/bend-24.json" > "$T/bend-6.json"
FLAGS=(--iterations 3 --cells 16 --nodes 64 --eval-points 5000)
export SPLATWARP=$B
timeout 300 sbatch --wait --array=0-1 --cpus-per-task=1 --chdir="$T" -o "$T/slurm-%A_%a.out" \
  "$SRC/samples/slurm/animate.sbatch" "$T/stripes.ply" "$T/bend-6.json" "$T/array" "${FLAGS[@]}" >"$T/sbatch.log" 2>&1 ||
  fail "sbatch --wait failed or timed out"
grep -h "shard" "$T"/slurm-*.out
"$B" animate --merge "$T/array" || fail "merge lists missing or failed frames"
"$B" -q animate "$T/stripes.ply" --spec "$T/bend-6.json" -o "$T/one" "${FLAGS[@]}" >/dev/null || fail "one-process run"
for f in 0000 0001 0002 0003 0004 0005; do
  cmp "$T/array/frames/deformed.$f.ply" "$T/one/frames/deformed.$f.ply" || fail "frame $f differs between the array and one process"
done
grep -q SLURM_ARRAY_TASK_ID "$T/array/manifest.shard-1.json" || fail "the shard manifest does not name SLURM_ARRAY_TASK_ID"
echo "PASS: 2-task Slurm array over 6 frames equals one process, byte for byte"
