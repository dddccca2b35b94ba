#include "SampleWarp.h"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/Error.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

/// Samples skinned per batch: bounds the skin-weight arrays ([batch,k] nodes and weights).
constexpr std::size_t kWarpBatch = std::size_t(1) << 16;
/// Samples (or cells) per parallel task.
constexpr std::size_t kGrain = 512;

template <typename Body>
void forRange(std::size_t b, std::size_t e, bool threaded, const Body& body)
{
    if (threaded)
        tbb::parallel_for(tbb::blocked_range<std::size_t>(b, e, kGrain),
                          [&](const tbb::blocked_range<std::size_t>& r) { body(r.begin(), r.end()); });
    else
        body(b, e);
}

} // namespace

Mat3d polarRotation(const Mat3d& m)
{
    Eigen::Matrix3d a;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a(i, j) = m.m[i][j];
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d u = svd.matrixU();
    if ((u * svd.matrixV().transpose()).determinant() < 0) u.col(2) = -u.col(2); // singular values sorted: col 2 smallest
    const Eigen::Matrix3d r = u * svd.matrixV().transpose();
    Mat3d out;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) out.m[i][j] = r(i, j);
    return out;
}

void warpSamples(SampleSet& samples, const DeformationGraph& graph, const NodeTransforms& transforms, bool threaded)
{
    const std::size_t m = samples.sampleCount();
    if (samples.restPositions.size() != 3 * m || samples.targetF.size() != m * std::size_t(samples.featureStride()))
        throw InputError("warpSamples: the sample set's arrays disagree in size");
    if (transforms.size() != graph.nodeCount())
        throw InputError(msg("warpSamples: ", transforms.size(), " node transforms for ", graph.nodeCount(), " nodes"));
    samples.warpedPositions.resize(3 * m);
    const std::size_t stride = std::size_t(samples.featureStride());
    for (std::size_t b0 = 0; b0 < m; b0 += kWarpBatch) {
        const std::size_t b1 = std::min(m, b0 + kWarpBatch);
        const SkinWeights w = graph.skinWeights(&samples.restPositions[3 * b0], b1 - b0, threaded);
        forRange(b0, b1, threaded, [&](std::size_t b, std::size_t e) {
            for (std::size_t s = b; s < e; ++s) {
                const float* p = &samples.restPositions[3 * s];
                const Vec3d x = skinPoint(graph, transforms, w, s - b0, Vec3d(p[0], p[1], p[2]));
                for (int k = 0; k < 3; ++k) samples.warpedPositions[3 * s + k] = float(x[k]);
                if (samples.shDegree > 0)
                    ShRotation(polarRotation(skinGradient(graph, transforms, w, s - b0)))
                        .apply(samples.shDegree, &samples.targetF[s * stride]);
            }
        });
    }
    computeCellGradients(samples, threaded);
}

void warpSamples(SampleSet& samples, const Deformation& deformation, bool threaded)
{
    warpSamples(samples, deformation.graph, deformation.transforms, threaded);
}

void computeCellGradients(SampleSet& samples, bool threaded)
{
    const int n = samples.samplesPerAxis;
    const std::size_t perCell = std::size_t(n) * n * n;
    const std::size_t cells = samples.cellCount();
    if (n < 2 || samples.warpedPositions.size() != 3 * cells * perCell)
        throw InputError("computeCellGradients: needs >= 2 samples per axis and warped positions for every cell");
    samples.cellGradient.resize(9 * cells);
    forRange(0, cells, threaded, [&](std::size_t b, std::size_t e) {
        for (std::size_t c = b; c < e; ++c) {
            Vec3d rest[8], warped[8], restMean, warpedMean;
            int q = 0;
            for (int a = 0; a < n; a += n - 1)
                for (int bb = 0; bb < n; bb += n - 1)
                    for (int cc = 0; cc < n; cc += n - 1, ++q) {
                        const std::size_t s = c * perCell + std::size_t((a * n + bb) * n + cc);
                        rest[q] = Vec3d(samples.restPositions[3 * s], samples.restPositions[3 * s + 1], samples.restPositions[3 * s + 2]);
                        warped[q] = Vec3d(samples.warpedPositions[3 * s], samples.warpedPositions[3 * s + 1],
                                          samples.warpedPositions[3 * s + 2]);
                        restMean += rest[q];
                        warpedMean += warped[q];
                    }
            restMean *= 1.0 / 8.0;
            warpedMean *= 1.0 / 8.0;
            Mat3d pq, qq;
            for (int k = 0; k < 8; ++k) {
                const Vec3d p = warped[k] - warpedMean, r = rest[k] - restMean;
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j) {
                        pq.m[i][j] += p[i] * r[j];
                        qq.m[i][j] += r[i] * r[j];
                    }
            }
            const Mat3d f = pq * qq.inverse();
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) samples.cellGradient[9 * c + 3 * i + j] = float(f.m[i][j]);
        }
    });
}

} // namespace splatwarp
