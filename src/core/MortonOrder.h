#pragma once
/// @file MortonOrder.h
/// @brief Points ordered along a Morton (Z-order) curve over their bounds, so that neighbours in
///        the order are neighbours in space: the block engine's point blocks and the skin
///        weights' runs of points that share their candidate nodes.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace splatwarp {

/// @brief Each point's Morton key (10 bits per axis: its cell of a 1024^3 lattice over the
///        points' bounds) and the order that sorts the keys, ties by index (a total order, so
///        the same permutation for any thread count).
struct MortonOrder {
    std::vector<std::uint64_t> key;   ///< [m] per point
    std::vector<std::uint32_t> order; ///< sorted position -> point

    /// @param x  [m,3] points (m < 2^32)
    MortonOrder(const float* x, std::size_t m, bool threaded);
};

} // namespace splatwarp
