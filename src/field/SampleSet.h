#pragma once
/// @file SampleSet.h
/// @brief The flat-array view of a sampled radiance field that vdb/SampleGrid hands to the
///        optimiser (src/, kernels/), so the maths never needs OpenVDB types.
///        M = sample count, C = active cell count, K = (shDegree+1)^2, N = Gaussian count.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace splatwarp {

struct SampleSet {
    int shDegree = 0;          ///< degree of the target SH features
    int samplesPerAxis = 4;    ///< n: each active cell holds n^3 samples (a fine cell: cellAxis)
    float cellSize = 0.0f;     ///< h: cell edge in world units (rest space)
    float spacing = 0.0f;      ///< h/n: rest sample spacing (of a coarse cell)

    std::vector<float> restPositions;   ///< [M,3] rest-space sample positions
    std::vector<float> warpedPositions; ///< [M,3] positions after the deformation (= rest when none)
    std::vector<float> targetF;         ///< [M,K,3] target radial SH features F* (rotated to the warped frame)
    std::vector<float> targetO;         ///< [M]     target opacity feature O*
    std::vector<std::int32_t> sampleCell; ///< [M] index of the sample's cell
    /// [C,9] row-major dimensionless deformation gradient F_k of each cell (identity at rest).
    /// The paper's A_k = h * F_k, so its low-pass term (lambda/n^2) A_k A_k^T = lambda (h/n)^2 F_k F_k^T.
    std::vector<float> cellGradient;
    std::vector<std::uint8_t> cellSkip; ///< [C] 1: zero target here and in every neighbour cell (skipped)
    /// Per-cell resolution, empty for the uniform lattice (every cell n^3 samples from c n^3).
    /// Else [C] samples per axis of each cell (n, or 2n in a fine cell) and [C+1] its first sample;
    /// a fine cell's (2n)^3 samples run octant by octant, n^3 each (compact blocks of n^3).
    std::vector<std::uint8_t> cellAxis;
    std::vector<std::uint64_t> cellFirst;

    std::size_t sampleCount() const { return targetO.size(); }
    std::size_t cellCount() const { return cellSkip.size(); }
    int featureStride() const { return 3 * (shDegree + 1) * (shDegree + 1); }
    /// Bytes each sample holds here: rest and warped positions, targets F and O, its cell.
    static std::size_t bytesPerSample(int shDegree)
    {
        return 12 + 12 + 4 * std::size_t(3 * (shDegree + 1) * (shDegree + 1)) + 4 + 4;
    }
    bool uniform() const { return cellAxis.empty(); }
    /// Samples per axis of cell c.
    int axisOf(std::size_t c) const { return uniform() ? samplesPerAxis : int(cellAxis[c]); }
    /// First sample of cell c (its samples are firstSampleOf(c) .. firstSampleOf(c+1)-1).
    std::size_t firstSampleOf(std::size_t c) const
    {
        return uniform() ? c * std::size_t(samplesPerAxis) * samplesPerAxis * samplesPerAxis : std::size_t(cellFirst[c]);
    }
    /// Whether the rest positions hold exactly the cells' samples (per-cell arrays of C entries).
    bool layoutConsistent() const
    {
        const std::size_t c = cellCount();
        if (!uniform() && (cellAxis.size() != c || cellFirst.size() != c + 1)) return false;
        return restPositions.size() == 3 * firstSampleOf(c);
    }
    /// Rest sample spacing of cell c: h / axisOf(c) (spacing itself for a coarse cell).
    float spacingOf(std::size_t c) const { return uniform() || cellAxis[c] == samplesPerAxis ? spacing : cellSize / float(cellAxis[c]); }
};

} // namespace splatwarp
