#!/usr/bin/env bash
# Behaviour snapshot for refactors: run a fixed set of CLI commands (every command that writes a
# model, a volume or an image) with one splatwarp binary and list the MD5 of each output. Two
# snapshots of the same outputs are identical line for line, so `diff A/md5.txt B/md5.txt` says
# whether a change altered behaviour. JSON reports are left out (they hold timings); for .vdb files
# the header's random UUID is left out. With ../shared/data present, real models and volumes too.
# Usage: bash scripts/snapshot.sh BUILD/tools/splatwarp OUT_DIR
set -euo pipefail
[ $# -eq 2 ] || { echo "usage: $0 SPLATWARP_BINARY OUT_DIR" >&2; exit 2; }
sw=$(realpath "$1"); dest=$2
cd "$(dirname "$0")/.."
# Outputs embed their paths (VDB metadata "source"): every snapshot runs in the same absolute
# folder, whichever checkout or binary it comes from, then moves.
o=/tmp/splatwarp-snapshot; rm -rf "$o" "$dest"; mkdir -p "$o"
s=samples/specs
run() { "$sw" -q "$@" > /dev/null; }
run sample stripes -o "$o/stripes.ply"
run sample ring -o "$o/ring.ply"
run to-vdb "$o/stripes.ply" -o "$o/stripes.vdb"
run to-vdb "$o/stripes.ply" -o "$o/stripes-bend.vdb" --spec $s/bend.json
run deform "$o/stripes.ply" --spec $s/bend.json -o "$o/bend" --vdb --render
run deform "$o/ring.ply" --spec $s/twist.json -o "$o/twist"
run deform "$o/stripes.ply" --spec $s/rigid.json -o "$o/rigid"
"$sw" -q eval --rest "$o/stripes.ply" --deformed "$o/bend/deformed.ply" --spec $s/bend.json > "$o/eval.txt"
run from-vdb "$o/stripes.vdb" -o "$o/fromvdb.ply" --iterations 10
run render "$o/bend/deformed.ply" -o "$o/render.png"
run animate "$o/stripes.ply" --spec $s/bend-24.json -o "$o/anim" --frames 0-2 --iterations 5
data=../shared/data
if [ -d "$data/splats" ]; then
  run convert $data/splats/guitar.compressed.ply "$o/guitar.ply"
  run convert $data/splats/lastchance.splat "$o/lastchance.ply"
  run to-vdb $data/splats/donut.ply -o "$o/donut.vdb" --cells 48
  run deform $data/splats/train-1000.ply --spec $s/bend.json -o "$o/train" --iterations 20 --vdb
  run from-vdb $data/volumes/smoke.vdb -o "$o/smoke.ply" --iterations 5
  run render $data/splats/playbot-31k-sh2.ply -o "$o/playbot.png"
fi
(cd "$o" && find . -type f ! -name '*.json' | sort | while read -r f; do
   case $f in
     *.vdb) echo "$(tail -c +58 "$f" | md5sum | cut -c1-32)  $f (after the header UUID)" ;;
     *) md5sum "$f" ;;
   esac
 done > ../splatwarp-snapshot.md5)
mv "$o.md5" "$o/md5.txt"
mv "$o" "$dest"
echo "snapshot: $(wc -l < "$dest/md5.txt") outputs listed in $dest/md5.txt"
