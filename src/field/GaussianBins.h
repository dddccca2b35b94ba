#pragma once
/// @file GaussianBins.h
/// @brief A sparse uniform hash grid of axis-aligned boxes (Gaussian extents): each box is
///        listed in every cell it overlaps, so a point finds every box that may contain it by
///        looking up its own cell. Used for feature evaluation and Stage II coverage.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/SmallMath.h"

namespace splatwarp {

class GaussianBins {
public:
    /// @brief Bin n boxes. Boxes with any hi < lo (empty extent) are left out.
    /// @param lo,hi     [n,3] box corners
    /// @param cellSize  cell edge (> 0); see suggestCellSize()
    void build(const float* lo, const float* hi, std::size_t n, float cellSize, bool threaded = true);

    /// @brief The boxes listed in the cell holding p, in ascending index order (a superset of
    ///        the boxes containing p). Returns the count; *first points at the indices.
    std::size_t candidates(const Vec3f& p, const std::uint32_t** first) const;

    /// @brief Append the boxes listed in every cell the box [lo, hi] overlaps (a superset of the
    ///        boxes it intersects; a box spanning several cells appears once per cell).
    void candidatesInBox(const float* lo, const float* hi, std::vector<std::uint32_t>& out) const;

    /// @brief A cell edge ~ the median box edge, doubled while the bins would hold more than
    ///        maxEntriesPerBox * n entries (huge boxes would otherwise span too many cells).
    static float suggestCellSize(const float* lo, const float* hi, std::size_t n, double maxEntriesPerBox = 32.0);

    float cellSize() const { return mCellSize; }
    /// @brief Total (cell, box) entries.
    std::size_t entryCount() const { return mItems.size(); }
    std::size_t cellCount() const { return mKeys.size(); }

private:
    std::uint64_t keyOf(const Vec3f& p) const;
    float mCellSize = 1.0f;
    std::vector<std::uint64_t> mKeys;    ///< [C] sorted occupied cell keys
    std::vector<std::uint32_t> mOffsets; ///< [C+1] start of each cell's list in mItems
    std::vector<std::uint32_t> mItems;   ///< box indices, per cell ascending
};

} // namespace splatwarp
