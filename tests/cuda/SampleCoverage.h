#pragma once
/// @file SampleCoverage.h
/// @brief The per-sample coverage (the CPU's layout before the block engine), kept as the
///        reference for the CUDA Stage II coverage, which still builds per-sample lists: the
///        Gaussians' (padded) boxes are binned (GaussianBins) and each sample keeps the boxes
///        (and slabs) containing it, stored both ways (CSR), each list ascending.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/Error.h"
#include "field/GaussianBins.h"
#include "stage2/Coverage.h"

namespace splatwarp::test {

class SampleCoverage {
public:
    /// @param lo,hi   [g,3] boxes (empty boxes, hi < lo, cover nothing)
    /// @param points  [s,3] sample positions
    /// @param slabs   [g] or null: a pair also needs the point inside box i's slabs
    void build(const float* lo, const float* hi, std::size_t g, const float* points, std::size_t s,
               bool threaded = true, const CoverageSlabs* slabs = nullptr);

    std::size_t pairCount() const { return mSampleItems.size(); }
    /// @brief Gaussians (box indices) covering sample j: [sampleBegin(j), sampleBegin(j+1)).
    const std::vector<std::uint32_t>& sampleOffsets() const { return mSampleOffsets; }
    const std::vector<std::uint32_t>& sampleItems() const { return mSampleItems; }
    /// @brief Samples covered by box i.
    const std::vector<std::uint32_t>& gaussianOffsets() const { return mGaussianOffsets; }
    const std::vector<std::uint32_t>& gaussianItems() const { return mGaussianItems; }

private:
    std::vector<std::uint32_t> mSampleOffsets, mSampleItems, mGaussianOffsets, mGaussianItems;
};

inline void SampleCoverage::build(const float* lo, const float* hi, std::size_t g, const float* points, std::size_t s,
                     bool threaded, const CoverageSlabs* slabs)
{
    GaussianBins bins;
    // Half the typical box: fewer candidates per sample for ~4x more bin entries (measured faster).
    bins.build(lo, hi, g, 0.5f * GaussianBins::suggestCellSize(lo, hi, g), threaded);
    auto inside = [&](std::uint32_t i, const float* p) {
        return p[0] >= lo[3 * i] && p[0] <= hi[3 * i] && p[1] >= lo[3 * i + 1] && p[1] <= hi[3 * i + 1] &&
               p[2] >= lo[3 * i + 2] && p[2] <= hi[3 * i + 2] && (!slabs || slabs[i].contains(p));
    };
    // Pass 1: count per sample; pass 2: fill. Both per sample, so the result is thread-independent.
    std::vector<std::uint64_t> count(s + 1, 0);
    const tbb::blocked_range<std::size_t> all(0, s, 512);
    auto countOp = [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t j = r.begin(); j != r.end(); ++j) {
            const float* p = points + 3 * j;
            const std::uint32_t* cand = nullptr;
            const std::size_t n = bins.candidates(Vec3f(p[0], p[1], p[2]), &cand);
            std::uint64_t c = 0;
            for (std::size_t k = 0; k < n; ++k) c += inside(cand[k], p);
            count[j + 1] = c;
        }
    };
    threaded ? tbb::parallel_for(all, countOp) : countOp(all);
    for (std::size_t j = 0; j < s; ++j) count[j + 1] += count[j];
    if (count[s] > 0xffffffffull) throw InputError(msg("Stage II coverage has ", count[s], " pairs; too many for 32-bit indices"));
    mSampleOffsets.assign(count.begin(), count.end());
    mSampleItems.resize(count[s]);
    auto fillOp = [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t j = r.begin(); j != r.end(); ++j) {
            const float* p = points + 3 * j;
            const std::uint32_t* cand = nullptr;
            const std::size_t n = bins.candidates(Vec3f(p[0], p[1], p[2]), &cand);
            std::uint32_t e = mSampleOffsets[j];
            for (std::size_t k = 0; k < n; ++k)
                if (inside(cand[k], p)) mSampleItems[e++] = cand[k];
        }
    };
    threaded ? tbb::parallel_for(all, fillOp) : fillOp(all);

    // Transpose, in sample order so each Gaussian's list is ascending.
    mGaussianOffsets.assign(g + 1, 0);
    for (std::uint32_t i : mSampleItems) ++mGaussianOffsets[i + 1];
    for (std::size_t i = 0; i < g; ++i) mGaussianOffsets[i + 1] += mGaussianOffsets[i];
    mGaussianItems.resize(mSampleItems.size());
    std::vector<std::uint32_t> cursor(mGaussianOffsets.begin(), mGaussianOffsets.end() - 1);
    for (std::size_t j = 0; j < s; ++j)
        for (std::uint32_t e = mSampleOffsets[j]; e < mSampleOffsets[j + 1]; ++e)
            mGaussianItems[cursor[mSampleItems[e]]++] = std::uint32_t(j);
}

} // namespace splatwarp::test
