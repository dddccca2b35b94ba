# Sourced by the study scripts: study_setup OUTDIR [MODEL...] sets `models` (the arguments, else
# the shared real models) and `bin`, and creates OUTDIR.
study_setup() {
  local data=../shared/data/splats
  mkdir -p "$1"
  shift
  models=("$@")
  [ ${#models[@]} -gt 0 ] || models=("$data/train-1000.ply" "$data/lastchance.splat" "$data/donut.ply" \
                                     "$data/playbot-31k-sh2.ply" "$data/guitar.compressed.ply")
  bin=${SPLATWARP_BIN:-build/tools/splatwarp}
}
