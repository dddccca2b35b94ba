#include "deform/WarpPoints.h"

#include <algorithm>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "deform/WarpMath.h"

namespace splatwarp {

namespace {
/// Points skinned per batch: bounds the skin-weight arrays ([batch,k] nodes and weights).
constexpr std::size_t kBatch = std::size_t(1) << 16;
constexpr std::size_t kGrain = 512;
} // namespace

void warpPoints(const DeformationGraph& graph, const NodeTransforms& transforms, const float* points,
                std::size_t count, float* warped, float* rotations, bool threaded)
{
    if (transforms.size() != graph.nodeCount())
        throw InputError(msg("warpPoints: ", transforms.size(), " node transforms for ", graph.nodeCount(), " nodes"));
    const std::vector<NodeAffine> nodes = nodeAffines(graph, transforms);
    const NodeAffine* affines = nodes.data();
    for (std::size_t b0 = 0; b0 < count; b0 += kBatch) {
        const std::size_t b1 = std::min(count, b0 + kBatch);
        const SkinWeights w = graph.skinWeights(points + 3 * b0, b1 - b0, threaded);
        const std::size_t k = std::size_t(w.k);
        // Batch-relative arrays: the weights are rows 0.. of this batch.
        parallelFor(b1 - b0, kGrain, threaded, [&](std::size_t p) {
            warpPoint(affines, w.nodes.data(), w.weights.data(), k, points + 3 * b0, p, warped + 3 * b0,
                      rotations ? rotations + 9 * b0 : nullptr);
        });
    }
}

} // namespace splatwarp
