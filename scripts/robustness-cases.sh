#!/usr/bin/env bash
# Hostile-user cases of issue 28 (batch paths, inputs as outputs, forged manifests, the zip, VDB
# metadata, CLI edges) against one splatwarp binary: one line per case, OK or BAD and why.
# Compare two binaries (before/after a change) by running it twice. Needs python3 with no extra
# modules. Usage: bash scripts/robustness-cases.sh SPLATWARP_BINARY WORK_DIR
set -uo pipefail
[ $# -eq 2 ] || { echo "usage: $0 SPLATWARP_BINARY WORK_DIR" >&2; exit 2; }
sw=$(realpath "$1"); w=$2
rm -rf "$w"; mkdir -p "$w"; w=$(realpath "$w"); cd "$w"
ok=0; bad=0
verdict() { # NAME CONDITION-THAT-MEANS-BAD WHY
  if eval "$2"; then echo "BAD  $1: $3"; bad=$((bad + 1)); else echo "OK   $1"; ok=$((ok + 1)); fi
}
jobs() { printf '{"jobs":[%s]}' "$1" > "$w/jobs.json"; }
"$sw" -q sample stripes --count 600 -o m.ply
spec=$(cd "$(dirname "$0")/.." 2>/dev/null; pwd)/samples/specs/bend.json
[ -f "$spec" ] || spec=$(dirname "$(dirname "$sw")")/../samples/specs/bend.json
anim='{"version":1,"units":"bbox","frames":2,"graph":{"nodes":24,"k":6,"seed":0},"handles":[{"box":{"min":[-0.01,-0.01,-0.01],"max":[0.15,1.01,1.01]},"fixed":true},{"box":{"min":[0.85,-0.01,-0.01],"max":[1.01,1.01,1.01]},"pivot":[0.5,1.05,0.5],"keys":[{"frame":0},{"frame":1,"rotate":{"axis":[0,0,1],"degrees":30}}]}]}'
echo "$anim" > anim.json
tv() { printf '{"kind":"to-vdb","input":"%s","output":"%s","args":["--cells","8"%s]}' "$w/m.ply" "$1" "${2:-}"; }
mkdir -p user && echo keep > user/deformed.ply && echo keep > user/x.vdb

# batch: paths out of DIR
jobs "$(tv "$w/user/abs.vdb")"; "$sw" -q batch jobs.json -o runs >/dev/null 2>&1
verdict "batch output absolute" '[ -e user/abs.vdb ]' "wrote $w/user/abs.vdb"
jobs "$(tv ../user/x.vdb)"; "$sw" -q batch jobs.json -o runs >/dev/null 2>&1
verdict "batch output ../ over a user file" '[ "$(cat user/x.vdb)" != keep ]' "overwrote user/x.vdb"
jobs "$(printf '{"kind":"deform","input":"%s","output":"../user","args":["--spec","%s","--stage1-only","--nodes","24"]}' "$w/m.ply" "$spec")"
"$sw" -q batch jobs.json -o runs >/dev/null 2>&1
verdict "batch --stage1-only aimed at a user folder" '[ ! -e user/deformed.ply ]' "deleted user/deformed.ply"
mkdir -p runs2 elsewhere && ln -sfn "$w/elsewhere" runs2/link
jobs "$(tv link/a.vdb)"; "$sw" -q batch jobs.json -o runs2 >/dev/null 2>&1
verdict "batch output through a symlinked subfolder" '[ -e elsewhere/a.vdb ]' "wrote through the symlink"
jobs "$(printf '{"kind":"from-vdb","input":"%s","output":"o.ply","args":["--report","%s","--iterations","1"]}' "$w/runs/x.vdb" "$w/user/r.json")"
"$sw" -q to-vdb m.ply -o runs-x.vdb --cells 8 >/dev/null 2>&1; mkdir -p runs && cp runs-x.vdb runs/x.vdb 2>/dev/null
"$sw" -q batch jobs.json -o runs >/dev/null 2>&1
verdict "batch args --report outside" '[ -e user/r.json ]' "wrote user/r.json"
jobs "$(tv same.vdb),$(tv same.vdb)"; "$sw" -q batch jobs.json -o runs3 >/dev/null 2>&1; rc=$?
verdict "batch two jobs, one output" '[ $rc -eq 0 ]' "exit 0"
cp jobs.json runs3/jobs.json 2>/dev/null || { mkdir -p runs3; cp jobs.json runs3/; }
jobs "$(tv jobs.json)"; cp jobs.json runs3/jobs.json; before=$(md5sum < runs3/jobs.json)
"$sw" -q batch runs3/jobs.json -o runs3 >/dev/null 2>&1
verdict "batch output onto its job list" '[ "$(md5sum < runs3/jobs.json)" != "$before" ]' "overwrote jobs.json"
# inputs as outputs
"$sw" -q to-vdb m.ply -o v0.vdb --cells 8 >/dev/null 2>&1; before=$(md5sum < v0.vdb)
cp v0.vdb v.vdb; "$sw" -q from-vdb v.vdb -o v.vdb --iterations 1 >/dev/null 2>&1
verdict "from-vdb -o its input" '[ "$(md5sum < v.vdb)" != "$before" ]' "overwrote the input"
cp v0.vdb v.vdb; "$sw" -q from-vdb v.vdb -o o.ply --report v.vdb --iterations 1 >/dev/null 2>&1
verdict "from-vdb --report onto its input" '[ "$(md5sum < v.vdb)" != "$before" ]' "overwrote the input"
cp v0.vdb v.vdb; "$sw" -q from-vdb v.vdb -o o.png --render --size 16 --iterations 1 >/dev/null 2>&1; rc=$?
verdict "from-vdb -o out.png --render" '[ $rc -eq 0 ]' "exit 0, the picture over the model"
# Frame 1 is bent (frame 0 is the rest pose: its bytes equal the input's).
mkdir -p a/frames && cp m.ply a/frames/deformed.0001.ply; before=$(md5sum < a/frames/deformed.0001.ply)
"$sw" -q animate a/frames/deformed.0001.ply --spec anim.json -o a --iterations 1 --cells 8 >/dev/null 2>&1
verdict "animate input in its own frames/" '[ "$(md5sum < a/frames/deformed.0001.ply)" != "$before" ]' "overwrote its input"
# merge and resume
"$sw" -q animate m.ply --spec anim.json -o s --stage1-only --shard 0/2 >/dev/null 2>&1
"$sw" -q animate m.ply --spec anim.json -o s --stage1-only --shard 1/2 >/dev/null 2>&1
rm -f s/frames/baseline.0001.ply; "$sw" -q animate --merge s >/dev/null 2>&1; rc=$?
verdict "merge: a done frame whose file is gone" '[ $rc -eq 0 ]' "exit 0"
"$sw" -q animate m.ply --spec anim.json -o s --stage1-only --shard 1/2 >/dev/null 2>&1
python3 - s/manifest.shard-1.json <<'PY'
import json,sys; m=json.load(open(sys.argv[1])); m["entries"][0]["files"][0]["fnv1a64"]="0"*16; json.dump(m,open(sys.argv[1],"w"))
PY
"$sw" -q animate --merge s >/dev/null 2>&1; rc=$?
verdict "merge: a wrong digest" '[ $rc -eq 0 ]' "exit 0"
"$sw" -q animate m.ply --spec anim.json -o r --stage1-only >/dev/null 2>&1
python3 - r/manifest.json <<'PY'
import json,sys; m=json.load(open(sys.argv[1])); m["entries"][1]["files"]=m["entries"][0]["files"]; json.dump(m,open(sys.argv[1],"w"))
PY
rm -f r/frames/baseline.0001.ply; "$sw" -q animate m.ply --spec anim.json -o r --stage1-only >/dev/null 2>&1
verdict "resume: an entry pointing at another frame's file" '[ ! -e r/frames/baseline.0001.ply ]' "frame 1 never written"
"$sw" -q animate m.ply --spec anim.json -o z --stage1-only --shard 0/2 >/dev/null 2>&1
"$sw" -q animate m.ply --spec anim.json -o z --stage1-only --shard 1/2 >/dev/null 2>&1
rm -f z/frames/baseline.0001.ply && ln -s /dev/zero z/frames/baseline.0001.ply
timeout 20 "$sw" -q animate --merge z --zip >/dev/null 2>&1; rc=$?
verdict "merge --zip of a symlink to /dev/zero" '[ $rc -eq 0 ] || [ $rc -eq 124 ]' "exit $rc, zip $(du -sh z/sequence.zip 2>/dev/null | cut -f1)"
rm -f z/frames/baseline.0001.ply z/frames/.sw*; mkfifo z/frames/baseline.0001.ply
timeout 20 "$sw" -q animate --merge z --zip >/dev/null 2>&1; rc=$?
verdict "merge --zip of a FIFO" '[ $rc -eq 124 ] || [ $rc -eq 0 ]' "exit $rc (124: hung)"
# VDB metadata, shards, CLI edges
"$sw" -q to-vdb m.ply -o own.vdb --cells 8 --sh-grids >/dev/null 2>&1
for d in -1 2147483647; do
  python3 -c "import sys" && cp own.vdb own$d.vdb
  if /usr/bin/python3 -c "import pyopenvdb" 2>/dev/null; then
    /usr/bin/python3 - own$d.vdb $d <<'PY'
import sys, pyopenvdb as vdb
g, meta = vdb.readAll(sys.argv[1]); meta["sh_degree"] = int(sys.argv[2]); vdb.write(sys.argv[1], grids=g, metadata=meta)
PY
    "$sw" -q from-vdb own$d.vdb -o o$d.ply --iterations 1 >/dev/null 2>&1; rc=$?
    verdict "from-vdb of sh_degree $d" '[ $rc -ne 1 ]' "exit $rc"
  fi
done
SLURM_ARRAY_TASK_ID=1 SLURM_ARRAY_TASK_MIN=5 SLURM_ARRAY_TASK_COUNT=4 "$sw" -q animate m.ply --spec anim.json -o sl --stage1-only >/dev/null 2>&1; rc=$?
verdict "SLURM_ARRAY_TASK_MIN above the ID" '[ $rc -eq 0 ]' "exit 0"
"$sw" info m.ply --json > /dev/full 2>/dev/null; rc=$?
verdict "info --json > /dev/full" '[ $rc -eq 0 ]' "exit 0"
"$sw" -q from-vdb v0.vdb -o g.ply --gaussians -1 >/dev/null 2>&1; rc=$?
verdict "from-vdb --gaussians -1" '[ $rc -ne 2 ]' "exit $rc"
printf '{"camera_angle_x":0,"w":32,"h":32,"frames":[{"file_path":"a","transform_matrix":[[1,0,0,0],[0,1,0,0],[0,0,1,5],[0,0,0,1]]}]}' > t.json
"$sw" -q render m.ply --camera t.json -o cam.png >/dev/null 2>&1; rc=$?
verdict "render with camera_angle_x 0" '[ $rc -eq 0 ]' "exit 0 (a blank image)"
echo "robustness-cases: $ok OK, $bad BAD"
