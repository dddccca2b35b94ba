#pragma once
/// @file Coverage.h
/// @brief Which Gaussians may touch which samples, in deformed space: the Gaussians' (padded)
///        boxes are binned (GaussianBins) and each sample keeps the boxes containing it. Stored
///        both ways (CSR): per sample for the forward pass, per Gaussian for the backward
///        gather, each list in ascending order so sums run in a fixed order.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace splatwarp {

class Coverage {
public:
    /// @param lo,hi   [g,3] boxes (empty boxes, hi < lo, cover nothing)
    /// @param points  [s,3] sample positions
    void build(const float* lo, const float* hi, std::size_t g, const float* points, std::size_t s,
               bool threaded = true);

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
