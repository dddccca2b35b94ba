#!/usr/bin/env bash
# Set up, build and run the main job on the bundled sample (generated, not downloaded):
# the stripes bar bent 90 degrees by samples/specs/bend.json. Outputs go to ./out/demo.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
OUT=out/demo
mkdir -p "$OUT"
SW=build/tools/splatwarp
$SW sample stripes -o "$OUT/stripes.ply"
$SW info "$OUT/stripes.ply"
# The rest field as a VDB volume (open it in vdb_print, vdb_render, Houdini, Blender).
$SW to-vdb "$OUT/stripes.ply" -o "$OUT/stripes.vdb"
# Stage I + Stage II, the deformed model's field, and a rest | Stage I | Stage II picture.
$SW deform "$OUT/stripes.ply" --spec samples/specs/bend.json -o "$OUT/bend" --vdb --render
echo "demo: outputs are in $OUT/ (bend/compare.png shows rest | Stage I | Stage II)"
