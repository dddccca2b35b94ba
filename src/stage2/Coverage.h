#pragma once
/// @file Coverage.h
/// @brief Coverage slabs: three slabs along a Gaussian's own axes that, with its padded box,
///        bound where it can reach. They cut the box down for thin or turned Gaussians, whose
///        boxes hold many samples they can never reach. Used by the CPU block coverage
///        (SampleBlocks.h) and the CUDA per-sample coverage.
#include <cmath>

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


} // namespace splatwarp
