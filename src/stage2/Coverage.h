#pragma once
/// @file Coverage.h
/// @brief Which Gaussians may touch which samples, in deformed space: the Gaussians' (padded)
///        boxes are binned (GaussianBins) and each sample keeps the boxes containing it. Stored
///        both ways (CSR): per sample for the forward pass, per Gaussian for the backward
///        gather, each list in ascending order so sums run in a fixed order. Optional slabs
///        (CoverageSlabs) cut the box down for thin or turned Gaussians, whose boxes hold many
///        samples they can never reach.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/HostDevice.h"

namespace splatwarp {

/// @brief Three slabs |axis[a] . (p - centre)| <= half[a] (a box in a rotated frame).
struct CoverageSlabs {
    float centre[3] = {0, 0, 0};
    float axis[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    float half[3] = {-1, -1, -1};

    /// @brief Whether p lies in all three slabs (float arithmetic, as in Coverage::build).
    SPLATWARP_HOST_DEVICE bool contains(const float* p) const
    {
        const float d[3] = {p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]};
        for (int a = 0; a < 3; ++a)
            if (!(std::fabs(axis[a][0] * d[0] + axis[a][1] * d[1] + axis[a][2] * d[2]) <= half[a])) return false;
        return true;
    }
};

class Coverage {
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

} // namespace splatwarp
