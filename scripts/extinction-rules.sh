#!/usr/bin/env bash
# The measurements behind `from-vdb --as extinction`'s opacity rule (src/fit/Extinction.h): for each
# candidate view-independent rule, a fitted uniform slab's transmittance through its centre along
# z, x, (1,0,1), (1,1,1) (splats / ray-marched volume), then smoke.vdb and wdas_cloud_sixteenth.vdb
# (from-vdb defaults) rendered from 4 orbit views against the ray-marched volume: mean |alpha
# difference|, mean signed difference (> 0: splats too opaque), PSNR of RGBA. "per-view ideal" gives
# every splat the exact centre-ray opacity for each camera (no single splat can): the floor set by
# the fit and the skirts. SPLATWARP_RULES_CACHE=DIR keeps the fitted real volumes as DIR/NAME.ply.
# Usage: bash scripts/extinction-rules.sh [BUILD_DIR]   (CPU: ~90 s plus the two fits)
set -euo pipefail
build=${1:-build}
exec "$build/tests/splatwarp_tests" --gtest_also_run_disabled_tests \
  --gtest_filter=FromVdb.DISABLED_ExtinctionRuleMeasurement
