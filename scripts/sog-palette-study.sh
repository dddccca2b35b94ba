#!/usr/bin/env bash
# The SOG palette study (docs/benchmarks.md, "SOG output: splat-transform's palette size"):
#   A. the k-means alone, exact or grouped (a study build of src/io/SogKmeans.cpp whose two
#      constants come from SOG_EXACT and SOG_GROUPS), on playbot and two synthetic SH-3 models;
#   B. `convert MODEL out.sog` with two binaries, alternated: wall, peak, size, md5, and the mean
#      PSNR of orbit renders of each SOG against its PLY.
# Usage: scripts/sog-palette-study.sh OUT BEFORE_BINARY AFTER_BINARY   (needs ../shared/data)
# PYTHON: a python3 with numpy (default: Debian's, which scripts/setup.sh gives numpy).
set -euo pipefail
cd "$(dirname "$0")/.."
py=${PYTHON:-/usr/bin/python3}
out=$1 before=$2 after=$3
mkdir -p "$out"
data=../shared/data/splats
[ -f "$out/mid.ply" ] || "$py" scripts/low-rank-sh-model.py "$out/mid.ply" 200000
[ -f "$out/big.ply" ] || "$py" scripts/low-rank-sh-model.py "$out/big.ply" 1000000
[ -f "$out/s300.ply" ] || "$after" sample stripes --count 300000 -o "$out/s300.ply" >/dev/null

# A. the k-means alone
sed -e 's|^constexpr std::size_t kExactUpTo = 4096;|static const std::size_t kExactUpTo = std::stoul(std::getenv("SOG_EXACT"));|' \
    -e 's|^constexpr std::size_t kNearGroups = 4;|static const std::size_t kNearGroups = std::stoul(std::getenv("SOG_GROUPS"));|' \
    -e 's|#include <cmath>|#include <cmath>\n#include <cstdlib>\n#include <string>|' src/io/SogKmeans.cpp > "$out/SogKmeansStudy.cpp"
cat > "$out/harness.cpp" <<'CPP'
// f_rest of a PLY as dumped by the study (float32 rows), k-means, then time, error, labels off
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include "io/SogFormat.h"
int main(int, char** argv)
{
    const int d = std::stoi(argv[2]);
    std::ifstream f(argv[1], std::ios::binary | std::ios::ate);
    std::vector<float> x(std::size_t(f.tellg()) / 4);
    f.seekg(0).read(reinterpret_cast<char*>(x.data()), std::streamsize(x.size() * 4));
    const std::size_t n = x.size() / std::size_t(d);
    const auto t0 = std::chrono::steady_clock::now();
    const splatwarp::sog::Palette p = splatwarp::sog::kmeans(x, n, d, std::stoul(argv[3]), 10, 1);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    auto dist = [&](std::size_t i, std::size_t c) {
        double e = 0;
        for (int j = 0; j < d; ++j) e += (double(x[i * d + j]) - p.centroids[c * d + j]) * (double(x[i * d + j]) - p.centroids[c * d + j]);
        return e;
    };
    double err = 0;
    for (std::size_t i = 0; i < n; ++i) err += dist(i, p.labels[i]);
    std::size_t off = 0, checked = 0;
    for (std::size_t i = 0; i < n; i += std::max<std::size_t>(1, n / 2000), ++checked) {
        std::size_t best = 0;
        for (std::size_t c = 1; c < p.count; ++c) best = dist(i, c) < dist(i, best) ? c : best;
        off += dist(i, best) < dist(i, p.labels[i]);
    }
    std::printf("%.2f s, error %.3g, %.1f%% off their nearest\n", s, err / double(n * d), 100.0 * off / checked);
}
CPP
g++ -O3 -std=c++17 -Isrc -I/usr/include/eigen3 "$out/harness.cpp" "$out/SogKmeansStudy.cpp" -ltbb -o "$out/harness"
dump() { "$py" - "$1" "$2" <<'PY'
import sys, numpy as np
with open(sys.argv[1], 'rb') as f:
    head = b''
    while not head.endswith(b'end_header\n'): head += f.read(1)
    lines = head.split(b'\n')
    names = [l.split()[-1].decode() for l in lines if l.startswith(b'property')]
    n = int([l for l in lines if l.startswith(b'element vertex')][0].split()[-1])
    a = np.frombuffer(f.read(n * 4 * len(names)), np.float32).reshape(n, len(names))
a[:, [i for i, x in enumerate(names) if x.startswith('f_rest_')]].astype(np.float32).tofile(sys.argv[2])
PY
}
dump "$data/playbot-31k-sh2.ply" "$out/playbot.f32"; dump "$out/mid.ply" "$out/mid.f32"; dump "$out/big.ply" "$out/big.f32"
for m in "playbot 24 16384" "mid 45 65536" "big 45 65536"; do
  set -- $m
  echo "$1, exact at 4096: $(SOG_EXACT=4096 SOG_GROUPS=4 "$out/harness" "$out/$1.f32" "$2" 4096)"
  [ "$1" = playbot ] && echo "$1, exact at $3: $(SOG_EXACT=65536 SOG_GROUPS=4 "$out/harness" "$out/$1.f32" "$2" "$3")"
  for g in 2 4 8; do echo "$1, $g groups at $3: $(SOG_EXACT=4096 SOG_GROUPS=$g "$out/harness" "$out/$1.f32" "$2" "$3")"; done
done

# B. convert, alternated, and the images
psnr() { # PLY SOG VIEWS: the mean PSNR of orbit views
  rm -rf "$out/v1" "$out/v2"
  "$after" render "$1" -o "$out/v1" --orbit "$3" --size 512x512 >/dev/null 2>&1
  "$after" render "$2" -o "$out/v2" --orbit "$3" --size 512x512 >/dev/null 2>&1
  for v in "$out"/v1/*.png; do
    "$after" compare "$v" "$out/v2/$(basename "$v")" --json | "$py" -c 'import json, sys; print(json.load(sys.stdin)["psnr"])'
  done | awk '{ s += $1 } END { printf "%.2f dB over %d views", s / NR, NR }'
}
for m in "$data/train-1000.ply 4" "$data/playbot-31k-sh2.ply 8" "$out/s300.ply 4" "$out/mid.ply 4" "$out/big.ply 4"; do
  set -- $m
  name=$(basename "$1" .ply)
  for round in 1 2; do
    for v in before after; do
      bin=$before; [ $v = after ] && bin=$after
      /usr/bin/time -f "$name $v: %e s, %M KB" "$bin" convert "$1" "$out/$name-$v.sog" 2>&1 | grep ' KB$'
    done
  done
  for v in before after; do
    echo "$name $v: $(stat -c %s "$out/$name-$v.sog") bytes, md5 $(md5sum < "$out/$name-$v.sog" | cut -c1-8), $(psnr "$1" "$out/$name-$v.sog" "$2")"
  done
done
