#include "deform/WarpPoints.h"

#include <algorithm>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/Error.h"
#include "deform/WarpKernel.h"

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
        auto body = [&](std::size_t b, std::size_t e) {
            for (std::size_t p = b; p < e; ++p) {
                // Batch-relative arrays: the weights are rows 0.. of this batch.
                warpPoint(affines, w.nodes.data(), w.weights.data(), k, points + 3 * b0, p - b0, warped + 3 * b0,
                          rotations ? rotations + 9 * b0 : nullptr);
            }
        };
        if (threaded)
            tbb::parallel_for(tbb::blocked_range<std::size_t>(b0, b1, kGrain),
                              [&](const tbb::blocked_range<std::size_t>& r) { body(r.begin(), r.end()); });
        else
            body(b0, b1);
    }
}

} // namespace splatwarp
