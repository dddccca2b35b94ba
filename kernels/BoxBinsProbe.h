#pragma once
/// @file BoxBinsProbe.h
/// @brief What the GPU box bins (BoxBinsCuda.cuh) make of a set of boxes: for the CUDA tests,
///        which cannot include the CUDA header. No CUDA types here.
#include <cstdint>
#include <vector>

namespace splatwarp::cuda {

/// @brief Result of one BoxBins::build.
struct BoxBinsProbe {
    bool built = false;        ///< false when no box is non-empty
    std::uint64_t entries = 0; ///< (cell, box) entries of the final cell size
    float inv = 0.0f;          ///< 1 / the final cell edge
};

/// @brief Bin boxes lo, hi [G,3] (host arrays, uploaded) on the current device.
/// @throws DeviceLimitError as BoxBins::build (more than 2^32 entries); Error for a CUDA failure
BoxBinsProbe probeBoxBins(const std::vector<float>& lo, const std::vector<float>& hi);

} // namespace splatwarp::cuda
