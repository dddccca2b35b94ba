#!/usr/bin/env bash
# Set up, build and run the main job on the bundled sample; outputs go to ./out/demo.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
OUT=out/demo
mkdir -p "$OUT"
SW=build/tools/splatwarp
$SW sample stripes -o "$OUT/stripes.ply"
$SW info "$OUT/stripes.ply"
$SW convert "$OUT/stripes.ply" "$OUT/stripes-converted.ply"
echo "demo: outputs are in $OUT/"
