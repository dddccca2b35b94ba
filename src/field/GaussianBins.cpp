#include "field/GaussianBins.h"

#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "core/Error.h"
#include "core/ParallelFor.h"

namespace splatwarp {
namespace {

// 21 bits per axis packed into 64; coordinates are clamped into range, which only merges far
// cells (the lookup stays a superset, so results stay exact).
constexpr std::int64_t kAxisBias = std::int64_t(1) << 20;
constexpr std::int64_t kAxisMax = (std::int64_t(1) << 21) - 1;

std::int64_t cellCoord(float v, float inv)
{
    const double c = std::floor(double(v) * inv) + double(kAxisBias);
    return std::int64_t(std::clamp(c, 0.0, double(kAxisMax)));
}

std::uint64_t packKey(std::int64_t x, std::int64_t y, std::int64_t z)
{
    return (std::uint64_t(x) << 42) | (std::uint64_t(y) << 21) | std::uint64_t(z);
}

/// Empty (hi < lo) or not finite: left out, as on the GPU (kernels/BoxBinsCuda.cuh).
bool emptyBox(const float* lo, const float* hi)
{
    for (int a = 0; a < 3; ++a)
        if (!std::isfinite(lo[a]) || !std::isfinite(hi[a])) return true;
    return !(hi[0] >= lo[0] && hi[1] >= lo[1] && hi[2] >= lo[2]);
}

} // namespace

std::uint64_t GaussianBins::keyOf(const Vec3f& p) const
{
    const float inv = 1.0f / mCellSize;
    return packKey(cellCoord(p.x, inv), cellCoord(p.y, inv), cellCoord(p.z, inv));
}

void GaussianBins::build(const float* lo, const float* hi, std::size_t n, float cellSize, bool threaded)
{
    if (!(cellSize > 0.0f) || !std::isfinite(cellSize)) throw InputError(msg("bin cell size ", cellSize, " must be positive"));
    mCellSize = cellSize;
    const float inv = 1.0f / cellSize;
    // Count entries per box, prefix-sum, then fill (key, box) in parallel.
    std::vector<std::uint64_t> start(n + 1, 0);
    auto cellRange = [&](std::size_t i, std::int64_t* a, std::int64_t* b) {
        for (int k = 0; k < 3; ++k) {
            a[k] = cellCoord(lo[3 * i + k], inv);
            b[k] = cellCoord(hi[3 * i + k], inv);
        }
    };
    parallelFor(n, 1024, threaded, [&](std::size_t i) {
        if (emptyBox(lo + 3 * i, hi + 3 * i)) return;
        std::int64_t a[3], b[3];
        cellRange(i, a, b);
        start[i + 1] = std::uint64_t((b[0] - a[0] + 1) * (b[1] - a[1] + 1) * (b[2] - a[2] + 1));
    });
    for (std::size_t i = 0; i < n; ++i) start[i + 1] += start[i];
    if (start[n] > 0xffffffffull) throw InputError(msg("Gaussian bins would hold ", start[n], " entries; cell size too small"));

    std::vector<std::pair<std::uint64_t, std::uint32_t>> entries(start[n]);
    parallelFor(n, 1024, threaded, [&](std::size_t i) {
        if (start[i + 1] == start[i]) return;
        std::int64_t a[3], b[3];
        cellRange(i, a, b);
        std::size_t e = start[i];
        for (std::int64_t x = a[0]; x <= b[0]; ++x)
            for (std::int64_t y = a[1]; y <= b[1]; ++y)
                for (std::int64_t z = a[2]; z <= b[2]; ++z) entries[e++] = {packKey(x, y, z), std::uint32_t(i)};
    });
    // (key, index) pairs are unique, so the sorted order is the same serial or parallel.
    if (threaded)
        tbb::parallel_sort(entries.begin(), entries.end());
    else
        std::sort(entries.begin(), entries.end());

    mKeys.clear();
    mOffsets.clear();
    mItems.resize(entries.size());
    for (std::size_t e = 0; e < entries.size(); ++e) {
        if (e == 0 || entries[e].first != entries[e - 1].first) {
            mKeys.push_back(entries[e].first);
            mOffsets.push_back(std::uint32_t(e));
        }
        mItems[e] = entries[e].second;
    }
    mOffsets.push_back(std::uint32_t(entries.size()));
}

std::size_t GaussianBins::candidates(const Vec3f& p, const std::uint32_t** first) const
{
    const std::uint64_t key = keyOf(p);
    const auto it = std::lower_bound(mKeys.begin(), mKeys.end(), key);
    if (it == mKeys.end() || *it != key) {
        *first = nullptr;
        return 0;
    }
    const std::size_t c = std::size_t(it - mKeys.begin());
    *first = mItems.data() + mOffsets[c];
    return mOffsets[c + 1] - mOffsets[c];
}

void GaussianBins::candidatesInBox(const float* lo, const float* hi, std::vector<std::uint32_t>& out) const
{
    if (emptyBox(lo, hi) || mKeys.empty()) return;
    const float inv = 1.0f / mCellSize;
    std::int64_t a[3], b[3];
    double span = 1;
    for (int k = 0; k < 3; ++k) {
        a[k] = cellCoord(lo[k], inv);
        b[k] = cellCoord(hi[k], inv);
        span *= double(b[k] - a[k] + 1);
    }
    auto append = [&](std::size_t c) {
        out.insert(out.end(), mItems.begin() + mOffsets[c], mItems.begin() + mOffsets[c + 1]);
    };
    if (span > double(mKeys.size())) { // a huge box: scan the occupied cells instead of its range
        for (std::size_t c = 0; c < mKeys.size(); ++c) {
            const std::uint64_t key = mKeys[c];
            const std::int64_t x = std::int64_t(key >> 42), y = std::int64_t((key >> 21) & kAxisMax),
                               z = std::int64_t(key & kAxisMax);
            if (x >= a[0] && x <= b[0] && y >= a[1] && y <= b[1] && z >= a[2] && z <= b[2]) append(c);
        }
        return;
    }
    for (std::int64_t x = a[0]; x <= b[0]; ++x)
        for (std::int64_t y = a[1]; y <= b[1]; ++y)
            for (std::int64_t z = a[2]; z <= b[2]; ++z) {
                const std::uint64_t key = packKey(x, y, z);
                const auto it = std::lower_bound(mKeys.begin(), mKeys.end(), key);
                if (it != mKeys.end() && *it == key) append(std::size_t(it - mKeys.begin()));
            }
}

float GaussianBins::suggestCellSize(const float* lo, const float* hi, std::size_t n, double maxEntriesPerBox)
{
    std::vector<float> edges;
    edges.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
        if (emptyBox(lo + 3 * i, hi + 3 * i)) continue;
        edges.push_back(std::max({hi[3 * i] - lo[3 * i], hi[3 * i + 1] - lo[3 * i + 1], hi[3 * i + 2] - lo[3 * i + 2]}));
    }
    if (edges.empty()) return 1.0f;
    std::nth_element(edges.begin(), edges.begin() + edges.size() / 2, edges.end());
    double cell = std::max(double(edges[edges.size() / 2]), 1e-12);
    for (int round = 0; round < 64; ++round) {
        double total = 0;
        for (std::size_t i = 0; i < n; ++i) {
            if (emptyBox(lo + 3 * i, hi + 3 * i)) continue;
            double cells = 1;
            for (int k = 0; k < 3; ++k) cells *= std::floor(hi[3 * i + k] / cell) - std::floor(lo[3 * i + k] / cell) + 1;
            total += cells;
        }
        if (total <= maxEntriesPerBox * double(edges.size())) break;
        cell *= 2;
    }
    return float(cell);
}

} // namespace splatwarp
