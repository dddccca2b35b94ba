#include "deform/WarpPoints.h"

#include <algorithm>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/Error.h"
#include "core/Polar.h"

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
    const AffineSkinning skinning(graph, transforms);
    for (std::size_t b0 = 0; b0 < count; b0 += kBatch) {
        const std::size_t b1 = std::min(count, b0 + kBatch);
        const SkinWeights w = graph.skinWeights(points + 3 * b0, b1 - b0, threaded);
        auto body = [&](std::size_t b, std::size_t e) {
            for (std::size_t p = b; p < e; ++p) {
                const float* x = points + 3 * p;
                const Vec3d y = skinning.point(w, p - b0, Vec3d(x[0], x[1], x[2]));
                for (int k = 0; k < 3; ++k) warped[3 * p + k] = float(y[k]);
                if (!rotations) continue;
                const Mat3d r = polarRotationFast(skinning.gradient(w, p - b0));
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j) rotations[9 * p + 3 * i + j] = float(r.m[i][j]);
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
