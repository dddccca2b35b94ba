#include "stage2/SampleBlocks.h"

#include <algorithm>
#include <cmath>

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
    for (std::size_t c = b.px.size() - lanes; c < b.px.size(); c += kSimdLanes) {
        const float* axes[3] = {b.px.data() + c, b.py.data() + c, b.pz.data() + c};
        for (int a = 0; a < 3; ++a) {
            b.chunkLo.push_back(*std::min_element(axes[a], axes[a] + kSimdLanes));
            b.chunkHi.push_back(*std::max_element(axes[a], axes[a] + kSimdLanes));
        }
    }
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

void BlockCoverage::build(const SampleBlocks& blocks, const float* lo, const float* hi, const CoverageSlabs* slabs,
                          std::size_t g, bool threaded)
{
    const std::size_t nb = blocks.count();
    GaussianBins bins; // the blocks' bounds, binned; each Gaussian looks up the cells its box overlaps
    bins.build(blocks.lo.data(), blocks.hi.data(), nb, GaussianBins::suggestCellSize(blocks.lo.data(), blocks.hi.data(), nb),
               threaded);
    mLists.resize(g);
    parallelFor(g, 64, threaded, [&](std::size_t k) {
        std::vector<std::uint32_t>& list = mLists[k];
        list.clear();
        bins.candidatesInBox(lo + 3 * k, hi + 3 * k, list);
        std::sort(list.begin(), list.end());
        list.erase(std::unique(list.begin(), list.end()), list.end());
        const float* gl = lo + 3 * k;
        const float* gh = hi + 3 * k;
        list.erase(std::remove_if(list.begin(), list.end(),
                                  [&](std::uint32_t b) {
                                      const float* bl = blocks.lo.data() + 3 * b;
                                      const float* bh = blocks.hi.data() + 3 * b;
                                      for (int a = 0; a < 3; ++a)
                                          if (bh[a] < gl[a] || bl[a] > gh[a]) return true;
                                      return slabs && !boxMeetsSlabs(bl, bh, slabs[k]);
                                  }),
                   list.end());
    });
    // Flatten per Gaussian, then transpose (Gaussians visited in order, so block lists ascend).
    mGaussianOffsets.assign(g + 1, 0);
    for (std::size_t k = 0; k < g; ++k) mGaussianOffsets[k + 1] = mGaussianOffsets[k] + mLists[k].size();
    mGaussianItems.resize(mGaussianOffsets[g]);
    mBlockOffsets.assign(nb + 1, 0);
    for (std::size_t k = 0; k < g; ++k) {
        std::copy(mLists[k].begin(), mLists[k].end(), mGaussianItems.begin() + std::ptrdiff_t(mGaussianOffsets[k]));
        for (std::uint32_t b : mLists[k]) ++mBlockOffsets[b + 1];
    }
    for (std::size_t b = 0; b < nb; ++b) mBlockOffsets[b + 1] += mBlockOffsets[b];
    if (mGaussianItems.size() > 0xffffffffull)
        throw InputError(msg("Stage II coverage has ", mGaussianItems.size(), " (block, Gaussian) pairs; too many for 32-bit indices"));
    mBlockItems.resize(mGaussianItems.size());
    mBlockEntryOf.resize(mGaussianItems.size());
    std::vector<std::uint64_t> cursor(mBlockOffsets.begin(), mBlockOffsets.end() - 1);
    std::size_t e = 0;
    for (std::size_t k = 0; k < g; ++k)
        for (std::uint32_t b : mLists[k]) {
            mBlockEntryOf[e++] = std::uint32_t(cursor[b]);
            mBlockItems[cursor[b]++] = std::uint32_t(k);
        }
}

} // namespace splatwarp
