#include "stage2/SampleBlocks.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "field/GaussianBins.h"

namespace splatwarp {
namespace {

void appendBlock(SampleBlocks& b, const float* x, std::size_t begin, std::size_t end)
{
    b.first.push_back(std::uint32_t(end));
    const std::size_t lanes = (end - begin + kSimdLanes - 1) / kSimdLanes * kSimdLanes;
    float lo[3] = {x[3 * begin], x[3 * begin + 1], x[3 * begin + 2]}, hi[3] = {lo[0], lo[1], lo[2]};
    for (std::size_t t = 0; t < lanes; ++t) {
        const std::size_t j = std::min(begin + t, end - 1); // padding repeats the last sample
        b.px.push_back(x[3 * j]);
        b.py.push_back(x[3 * j + 1]);
        b.pz.push_back(x[3 * j + 2]);
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], x[3 * j + std::size_t(a)]);
            hi[a] = std::max(hi[a], x[3 * j + std::size_t(a)]);
        }
    }
    b.slot.push_back(std::uint32_t(b.px.size()));
    float chunks[6][kChunkSlots];
    for (int c = 0; c < kChunkSlots; ++c)
        for (int a = 0; a < 3; ++a) {
            chunks[a][c] = std::numeric_limits<float>::quiet_NaN(); // never meets a Gaussian
            chunks[3 + a][c] = 0.0f;
        }
    const std::size_t s0 = b.px.size() - lanes;
    for (std::size_t c = 0; c < lanes / kSimdLanes; ++c) {
        const float* axes[3] = {b.px.data() + s0 + c * kSimdLanes, b.py.data() + s0 + c * kSimdLanes,
                                b.pz.data() + s0 + c * kSimdLanes};
        for (int a = 0; a < 3; ++a) {
            const float cl = *std::min_element(axes[a], axes[a] + kSimdLanes);
            const float ch = *std::max_element(axes[a], axes[a] + kSimdLanes);
            // Rounded outwards: centre +- half holds [cl, ch].
            const float centre = 0.5f * (cl + ch);
            chunks[a][c] = centre;
            chunks[3 + a][c] = std::nextafter(std::max(ch - centre, centre - cl), std::numeric_limits<float>::infinity());
        }
    }
    b.chunks.insert(b.chunks.end(), &chunks[0][0], &chunks[0][0] + 6 * kChunkSlots);
    b.lo.insert(b.lo.end(), lo, lo + 3);
    b.hi.insert(b.hi.end(), hi, hi + 3);
}

} // namespace

SampleBlocks SampleBlocks::build(const float* x, const std::int32_t* cell, std::size_t s)
{
    SampleBlocks b;
    b.first.push_back(0);
    b.slot.push_back(0);
    std::size_t begin = 0;
    for (std::size_t j = 1; j <= s; ++j)
        if (j == s || cell[j] != cell[begin] || j - begin == std::size_t(kMaxBlockSamples)) {
            appendBlock(b, x, begin, j);
            begin = j;
        }
    return b;
}

bool boxMeetsSlabs(const float* lo, const float* hi, const CoverageSlabs& slabs)
{
    for (int a = 0; a < 3; ++a) {
        double centre = 0, reach = 0;
        for (int k = 0; k < 3; ++k) {
            const double n = slabs.axis[a][k];
            centre += n * (0.5 * (double(lo[k]) + double(hi[k])) - double(slabs.centre[k]));
            reach += std::fabs(n) * 0.5 * (double(hi[k]) - double(lo[k]));
        }
        // The slab test in Coverage is float arithmetic; a relative allowance keeps this a superset.
        if (!(std::fabs(centre) - reach <= double(slabs.half[a]) * (1 + 1e-6) + 1e-6 * reach)) return false;
    }
    return true;
}

namespace {

/// Largest half size of any block per axis (blocks with non-finite bounds left out).
void largestHalf(const SampleBlocks& blocks, float* half)
{
    half[0] = half[1] = half[2] = 0.0f;
    for (std::size_t b = 0; b < blocks.count(); ++b)
        for (int a = 0; a < 3; ++a) {
            const float h = 0.5f * (blocks.hi[3 * b + std::size_t(a)] - blocks.lo[3 * b + std::size_t(a)]);
            if (std::isfinite(h)) half[a] = std::max(half[a], h);
        }
}

bool finiteBox(const float* lo, const float* hi)
{
    for (int a = 0; a < 3; ++a)
        if (!std::isfinite(lo[a]) || !std::isfinite(hi[a])) return false;
    return true;
}

} // namespace

void BlockCoverage::build(const SampleBlocks& blocks, const float* lo, const float* hi, const CoverageSlabs* slabs,
                          std::size_t g, bool threaded)
{
    const std::size_t nb = blocks.count();
    // Each Gaussian's box grown by the largest block half size holds the centre of every block
    // its box meets, so one lookup per block (the bin of its centre) finds all its Gaussians,
    // ascending and once each; the exact box and slab tests then filter them.
    float grow[3];
    largestHalf(blocks, grow);
    std::vector<float> glo(3 * g), ghi(3 * g);
    parallelFor(g, 1024, threaded, [&](std::size_t k) {
        const bool empty = !(hi[3 * k] >= lo[3 * k] && hi[3 * k + 1] >= lo[3 * k + 1] && hi[3 * k + 2] >= lo[3 * k + 2]);
        for (std::size_t a = 0; a < 3; ++a) {
            const float l = lo[3 * k + a], h = hi[3 * k + a];
            const float pad = grow[a] * (1 + 1e-3f) + 1e-5f * (std::fabs(l) + std::fabs(h)); // beyond float rounding
            glo[3 * k + a] = empty ? std::numeric_limits<float>::quiet_NaN() : l - pad; // NaN: left out of the bins
            ghi[3 * k + a] = empty ? std::numeric_limits<float>::quiet_NaN() : h + pad;
        }
    });
    GaussianBins bins;
    bins.build(glo.data(), ghi.data(), g, GaussianBins::suggestCellSize(glo.data(), ghi.data(), g), threaded);
    mLists.resize(nb);
    parallelFor(nb, 16, threaded, [&](std::size_t b) {
        std::vector<std::uint32_t>& list = mLists[b];
        list.clear();
        const float* bl = blocks.lo.data() + 3 * b;
        const float* bh = blocks.hi.data() + 3 * b;
        if (!finiteBox(bl, bh)) return;
        const std::uint32_t* first = nullptr;
        const std::size_t n = bins.candidates(Vec3f(0.5f * (bl[0] + bh[0]), 0.5f * (bl[1] + bh[1]), 0.5f * (bl[2] + bh[2])), &first);
        for (std::size_t i = 0; i < n; ++i) {
            const std::uint32_t k = first[i];
            const float* gl = lo + 3 * k;
            const float* gh = hi + 3 * k;
            if (bh[0] < gl[0] || bl[0] > gh[0] || bh[1] < gl[1] || bl[1] > gh[1] || bh[2] < gl[2] || bl[2] > gh[2]) continue;
            if (slabs && !boxMeetsSlabs(bl, bh, slabs[k])) continue;
            list.push_back(k);
        }
    });
    flatten(nb, g);
}

void BlockCoverage::flatten(std::size_t nb, std::size_t g)
{
    // Block-major lists as found, then the transpose (blocks visited in order, so each
    // Gaussian's blocks ascend).
    mBlockOffsets.assign(nb + 1, 0);
    for (std::size_t b = 0; b < nb; ++b) mBlockOffsets[b + 1] = mBlockOffsets[b] + mLists[b].size();
    const std::uint64_t pairs = mBlockOffsets[nb];
    if (pairs > 0xffffffffull)
        throw InputError(msg("Stage II coverage has ", pairs, " (block, Gaussian) pairs; too many for 32-bit indices"));
    mBlockItems.resize(pairs);
    mGaussianOffsets.assign(g + 1, 0);
    for (std::size_t b = 0; b < nb; ++b) {
        std::copy(mLists[b].begin(), mLists[b].end(), mBlockItems.begin() + std::ptrdiff_t(mBlockOffsets[b]));
        for (std::uint32_t k : mLists[b]) ++mGaussianOffsets[k + 1];
    }
    for (std::size_t k = 0; k < g; ++k) mGaussianOffsets[k + 1] += mGaussianOffsets[k];
    mGaussianItems.resize(pairs);
    mBlockEntryOf.resize(pairs);
    std::vector<std::uint64_t> cursor(mGaussianOffsets.begin(), mGaussianOffsets.end() - 1);
    for (std::size_t b = 0; b < nb; ++b)
        for (std::uint64_t e = mBlockOffsets[b]; e < mBlockOffsets[b + 1]; ++e) {
            const std::uint64_t at = cursor[mBlockItems[e]]++;
            mGaussianItems[at] = std::uint32_t(b);
            mBlockEntryOf[at] = std::uint32_t(e);
        }
}

} // namespace splatwarp
