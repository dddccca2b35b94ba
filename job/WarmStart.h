#pragma once
/// @file WarmStart.h
/// @brief Stage II warm start for `animate --warm-start`: frames run in pairs (2k, 2k+1); the even
///        frame starts Stage II at its Stage I model as `deform` does, the odd frame at its Stage I
///        model plus the even frame's Stage II correction (fitted minus Stage I, per parameter; a
///        relative rotation for the quaternions), unless that start is far worse than the even frame's
///        fit (rejectsWarmStart: then it starts cold too). Measured on the stripes bend in
///        docs/lab/animation-study.md: longer chains drift (each warm frame keeps the last one's local
///        optimum), pairs do not.
#include <cstdint>
#include <vector>

#include "job/Shard.h"
#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief Frames per warm-start chain: its first frame starts cold, the others from the frame before.
constexpr int kWarmChain = 2;

/// @brief Whether frame f starts from frame f-1's correction (absolute frame numbers, so a frame's
///        bytes never depend on --frames, the shard or a resume).
inline bool startsWarm(int frame) { return frame % kWarmChain != 0; }

/// @brief An odd frame goes back to the cold start when its warm start's training energy exceeds
///        this many times the even frame's fitted energy. Set on the stripes bend
///        (docs/lab/animation-study.md), the one case measured: 2.08 on frame 7, where warm was 9.8%
///        worse than cold (judged error); 1.74 on frame 9 (even), 1.01-1.51 on frames 11-23 (warm
///        better); 1.9 is between 1.74 and 2.08. Stage I energies there are ~5x the fitted ones.
constexpr double kWarmEnergyLimit = 1.9;

/// @brief Whether a warm start of training energy `warmStart` is rejected after a frame before
///        fitted to `previousFit` (ties and below: kept).
inline bool rejectsWarmStart(double warmStart, double previousFit) { return !(warmStart <= kWarmEnergyLimit * previousFit); }

/// @brief What Stage II changed on each Gaussian of one frame (zero where it did not move).
struct StageTwoCorrection {
    std::vector<float> means, logScales, opacities, sh; ///< fitted - Stage I, same layout as GaussianCloud
    std::vector<float> rotations;                       ///< [N,4] unit q_fitted * conj(q_stage1)
};

/// @brief The correction fitted - stage1 (same size and SH degree).
StageTwoCorrection stageTwoCorrection(const GaussianCloud& stage1, const GaussianCloud& fitted);

/// @brief Add a correction to the Gaussians of `start` flagged in `moving` (Stage II leaves the others as they are).
void applyCorrection(const StageTwoCorrection& c, const std::vector<std::uint8_t>& moving, GaussianCloud& start);

/// @brief This shard's frames of `frames` (ascending) under warm start: whole chains, the chains
///        split into `shard.count` contiguous ranges (shard I takes the I-th), so a shard recomputes
///        at most the frame before its first one.
std::vector<int> warmShardFrames(const std::vector<int>& frames, const Shard& shard);

} // namespace splatwarp
