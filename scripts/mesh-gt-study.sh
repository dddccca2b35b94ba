#!/usr/bin/env bash
# The paper's image judge on meshes (issue 31): each mesh is turned into splats (from-mesh, CPU),
# deformed by each spec, and judged by `eval --mesh` (the mesh deformed by the same graph, 200 views
# over the sphere): Stage I with the paper's polar shape (--stage1-only --stage1-shape polar), the
# paper's Stage II (--recipe paper), the default Stage I (affine, baseline.ply), the default result
# (deformed.ply), the default held to the input's Gaussian count (--max-gaussians 1x) and the
# default with the keep's two other modes (--keep regions: no per-Gaussian choice; --keep fit: no
# keep); PSNR / SSIM, the field judge's opacity error of paper / default / regions, the Gaussian
# counts and the times. One Markdown row per mesh x spec; the rest models' held-out
# scores first.
#   bash scripts/mesh-gt-study.sh OUTDIR            (MESHES="spot bunny stripes", SPECS="bend twist stretch")
# ITERATIONS, SIZE, VIEWS, EVAL_VIEWS, EVAL_SIZE choose the training and judging budgets; ABLATIONS=0
# runs only the README's columns (polar, paper, default), "-" in the others (half the time a row).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: mesh-gt-study.sh OUTDIR}
bin=${SPLATWARP:-build/tools/splatwarp}
data=${SPLATWARP_DATA:-../shared/data}
meshes=(${MESHES:-spot bunny stripes})
specs=(${SPECS:-bend twist stretch})
iterations=${ITERATIONS:-5000}
size=${SIZE:-256}
views=${VIEWS:-100}
eval_views=${EVAL_VIEWS:-200}
eval_size=${EVAL_SIZE:-256}
# The ablation columns: output suffix and the flags beside the default's.
ablations=()
[ "${ABLATIONS:-1}" = 1 ] && ablations=("1x --max-gaussians 1x" "regions --keep regions" "keepfit --keep fit")
mkdir -p "$out"

# The paper's Stripes: a 4 x 1 x 1 bar of 8 coloured bands (each its own subdivided box, so the
# bands stay sharp), fine enough along x for a bend to curve it.
python3 - "$out/stripes.obj" <<'PY'
import sys
colours = [(0.88, 0.2, 0.16), (0.95, 0.85, 0.3), (0.2, 0.7, 0.3), (0.15, 0.35, 0.85),
           (0.9, 0.9, 0.9), (0.55, 0.2, 0.7), (0.05, 0.05, 0.07), (0.95, 0.55, 0.15)]
v, f = [], []
def quad_grid(origin, du, dv, nu, nv, c):
    base = len(v)
    for j in range(nv + 1):
        for i in range(nu + 1):
            p = [origin[k] + du[k] * i / nu + dv[k] * j / nv for k in range(3)]
            v.append((p, c))
    for j in range(nv):
        for i in range(nu):
            a = base + j * (nu + 1) + i
            f.append((a, a + 1, a + nu + 2, a + nu + 1))
for b, c in enumerate(colours):
    x0, x1 = -2 + 0.5 * b, -1.5 + 0.5 * b
    L, n, m = x1 - x0, 8, 8
    quad_grid((x0, -0.5, -0.5), (L, 0, 0), (0, 1, 0), n, m, c)   # z = -0.5
    quad_grid((x0, -0.5, 0.5), (0, 1, 0), (L, 0, 0), m, n, c)    # z = +0.5
    quad_grid((x0, -0.5, -0.5), (0, 0, 1), (L, 0, 0), m, n, c)   # y = -0.5
    quad_grid((x0, 0.5, -0.5), (L, 0, 0), (0, 0, 1), n, m, c)    # y = +0.5
    if b == 0: quad_grid((x0, -0.5, -0.5), (0, 1, 0), (0, 0, 1), m, m, c)
    if b == len(colours) - 1: quad_grid((x1, -0.5, -0.5), (0, 0, 1), (0, 1, 0), m, m, c)
with open(sys.argv[1], "w") as o:
    for p, c in v: o.write("v %g %g %g %g %g %g\n" % (*p, *c))
    for q in f: o.write("f %d %d %d %d\n" % tuple(i + 1 for i in q))
PY

mesh_args() {
  case "$1" in
    spot) echo "$data/meshes/spot/spot_triangulated.obj --texture $data/meshes/spot/spot_texture.png" ;;
    bunny) echo "$data/meshes/bunny/bun_zipper.ply --procedural-colour" ;;
    stripes) echo "$out/stripes.obj" ;;
  esac
}

echo "## Rest models (from-mesh: $views views of ${size}x$size, $iterations steps, SH 0)"
echo "| mesh | held-out PSNR / SSIM | Gaussians | train s (wall) |"
echo "|---|---|---|---|"
for m in "${meshes[@]}"; do
  dir="$out/$m"
  mkdir -p "$dir"
  if [ ! -f "$dir/rest.ply" ]; then
    # shellcheck disable=SC2046
    "$bin" from-mesh $(mesh_args "$m") -o "$dir/rest.ply" --size "$size" --views "$views" --iterations "$iterations" \
      --sh-degree 0 --report "$dir/rest.json" > "$dir/from-mesh.log" 2>&1 || { echo "| $m | failed: see $dir/from-mesh.log |"; continue; }
  fi
  python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); print("| %s | %.2f dB / %.4f | %d | %.0f |" % (sys.argv[2], r["test"]["psnr"], r["test"]["ssim"], r["gaussians"], r["seconds"]))' "$dir/rest.json" "$m"
done

echo
echo "## Deformed: eval --mesh ($eval_views views of ${eval_size}x$eval_size), PSNR dB / SSIM"
echo "| mesh | spec | rest model | Stage I polar | paper (Stage II) | Stage I (default, affine) | default | default at 1x | --keep regions | --keep fit | default - polar | default - paper | field error: paper / default / regions | Gaussians rest -> default | deform s |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for m in "${meshes[@]}"; do
  dir="$out/$m"
  [ -f "$dir/rest.ply" ] || continue
  for s in "${specs[@]}"; do
    run="$dir/$s"
    spec="samples/specs/$s.json"
    start=$(date +%s.%N)
    "$bin" -q deform "$dir/rest.ply" --spec "$spec" -o "$run" --device cpu > "$run.log" 2>&1 || { echo "| $m | $s | failed: see $run.log |"; continue; }
    end=$(date +%s.%N)
    "$bin" -q deform "$dir/rest.ply" --spec "$spec" -o "$run-polar" --device cpu --stage1-only --stage1-shape polar > "$run-polar.log" 2>&1
    "$bin" -q deform "$dir/rest.ply" --spec "$spec" -o "$run-paper" --device cpu --recipe paper > "$run-paper.log" 2>&1
    for a in "${ablations[@]}"; do
      read -r name flags <<< "$a"
      # shellcheck disable=SC2086
      "$bin" -q deform "$dir/rest.ply" --spec "$spec" -o "$run-$name" --device cpu $flags > "$run-$name.log" 2>&1
    done
    # shellcheck disable=SC2046
    judge() { "$bin" -q eval --mesh $(mesh_args "$m") --rest "$dir/rest.ply" --spec "$spec" --deformed "$1" \
                --views "$eval_views" --size "$eval_size" --json "${@:2}"; }
    judge "$run-polar/baseline.ply" > "$run/judge-polar.json"
    judge "$run-paper/deformed.ply" > "$run/judge-paper.json"
    judge "$run/baseline.ply" > "$run/judge-stage1.json"
    rm -f "$run/judge-1x.json" "$run/judge-regions.json" "$run/judge-keepfit.json" # none left from an earlier run
    for a in "${ablations[@]}"; do
      read -r name _ <<< "$a"
      judge "$run-$name/deformed.ply" > "$run/judge-$name.json"
    done
    judge "$run/deformed.ply" --montage "$run/worst.png" > "$run/judge-default.json"
    python3 - "$run" "$m" "$s" "$dir/rest.json" "$(echo "$end - $start" | bc)" <<'PY'
import json, os, sys, struct
run, m, s, rest, secs = sys.argv[1:6]
def j(n):
    p = "%s/judge-%s.json" % (run, n)
    return json.load(open(p)) if os.path.exists(p) else None
def count(p):
    with open(p, "rb") as f:
        for line in f:
            if line.startswith(b"element vertex"): return int(line.split()[2])
p, q, a, d, o, g, k = j("polar"), j("paper"), j("stage1"), j("default"), j("1x"), j("regions"), j("keepfit")
def field(d):
    if not os.path.exists(d + "/report.json"): return "-"
    return "%.3f" % json.load(open(d + "/report.json"))["stage2"]["fieldError"]["opacity"]
r = json.load(open(rest))
cell = lambda x: "%.2f / %.4f" % (x["psnr"], x["ssim"]) if x else "-"
print("| %s | %s | %.2f / %.4f | %s | %s | %s | %s | %s | %s | %s | %+.2f dB | %+.2f dB | %s / %s / %s | %d -> %d | %.0f |" % (
      m, s, r["test"]["psnr"], r["test"]["ssim"], cell(p), cell(q), cell(a), cell(d), cell(o), cell(g), cell(k), d["psnr"] - p["psnr"],
      d["psnr"] - q["psnr"], field(run + "-paper"), field(run), field(run + "-regions") if g else "-", r["gaussians"], count(run + "/deformed.ply"),
      float(secs)))
PY
  done
done
