#pragma once
/// @file BlockFeatures.h
/// @brief F and O at points grouped by cell, with the Stage II block engine (SampleBlocks.h,
///        BlockLoops.h): each Gaussian is listed only for the blocks its cutoff box and its
///        axis slabs meet, and the weights run vectorised over a block's points. The rest
///        targets of a sample grid use it (a cell's samples are one block). Same sums in the
///        same (ascending Gaussian) order per point as evaluateFeatures().
#include <cstdint>
#include <memory>
#include <vector>

#include "core/GaussianCloud.h"
#include "core/Device.h"
#include "field/FeatureField.h"

namespace splatwarp {

/// @param points  [m,3]; cell: [m] cell of each point (runs of equal cell form the blocks)
/// @param features [m,stride] out (may be null); opacity: [m] out (may be null)
/// @return pairsTested counts (block point, Gaussian) lanes tested; pairsContributing those >= cutoff
FeatureStats evaluateBlockFeatures(const GaussianCloud& cloud, const float* points, const std::int32_t* cell, std::size_t m,
                                   const FeatureOptions& options, float* features, float* opacity);

/// @brief F and O at any points (held-out and validation points: not grouped by cell), with the
///        block engine: the points are put in Morton order over their bounds, cut into blocks of
///        at most kMaxBlockSamples within one cell of the coarsest lattice that holds about 32
///        points a cell, evaluated as evaluateBlockFeatures() does and put back in their order.
///        Same bits as evaluateFeatures() (the same sums in the same order per point).
FeatureStats evaluatePointFeatures(const GaussianCloud& cloud, const float* points, std::size_t m,
                                   const FeatureOptions& options, float* features, float* opacity);

struct SampleBlocks;

/// @brief Points put in Morton order and cut into blocks once, as evaluatePointFeatures() does,
///        for evaluating many models at the same points (the judges' points).
class PointBlocks {
public:
    PointBlocks(const float* points, std::size_t m, bool threaded);
    ~PointBlocks();
    /// False where the block engine does not take these points (a non-finite point, none, or
    ///  more than 2^31): evaluatePointFeatures() evaluates them one by one.
    bool usable() const { return mBlocks != nullptr; }
    /// @brief F and O of a model at the points, in their order (usable() only).
    FeatureStats evaluate(const GaussianCloud& cloud, const FeatureOptions& options, float* features, float* opacity) const;

private:
    std::vector<std::uint32_t> mOrder;    ///< sorted position -> point
    std::unique_ptr<SampleBlocks> mBlocks; ///< of the sorted points
};

/// @brief evaluatePointFeatures() on the CPU, evaluateFeaturesOn() (field/FeatureDevice.h) where
///        options.device is CUDA. @return the device that ran
Device evaluatePointsOn(const GaussianCloud& cloud, const float* points, std::size_t m, const FeatureOptions& options,
                        float* features, float* opacity);

} // namespace splatwarp
