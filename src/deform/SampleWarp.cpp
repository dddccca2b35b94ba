#include "deform/SampleWarp.h"

#include <algorithm>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "deform/WarpPoints.h"
#include "deform/WarpMath.h"

namespace splatwarp {

namespace {

/// Samples warped per batch: bounds the per-batch rotation array ([batch,9]).
constexpr std::size_t kWarpBatch = std::size_t(1) << 16;
/// Samples (or cells) per parallel task.
constexpr std::size_t kGrain = 512;

} // namespace

void checkWarpSamples(const SampleSet& samples, const DeformationGraph& graph, const NodeTransforms& transforms)
{
    const std::size_t m = samples.sampleCount();
    if (samples.restPositions.size() != 3 * m || samples.targetF.size() != m * std::size_t(samples.featureStride()))
        throw InputError("warpSamples: the sample set's arrays disagree in size");
    if (transforms.size() != graph.nodeCount())
        throw InputError(msg("warpSamples: ", transforms.size(), " node transforms for ", graph.nodeCount(), " nodes"));
}

void warpSamples(SampleSet& samples, const DeformationGraph& graph, const NodeTransforms& transforms, bool threaded)
{
    checkWarpSamples(samples, graph, transforms);
    const std::size_t m = samples.sampleCount();
    samples.warpedPositions.resize(3 * m);
    const std::size_t stride = std::size_t(samples.featureStride());
    const bool rotate = samples.shDegree > 0;
    std::vector<float> rotations(rotate ? 9 * std::min(m, kWarpBatch) : 0);
    const ShRotationTables& tables = shRotationTables();
    for (std::size_t b0 = 0; b0 < m; b0 += kWarpBatch) {
        const std::size_t b1 = std::min(m, b0 + kWarpBatch);
        warpPoints(graph, transforms, &samples.restPositions[3 * b0], b1 - b0, &samples.warpedPositions[3 * b0],
                   rotate ? rotations.data() : nullptr, threaded);
        if (!rotate) continue;
        parallelFor(b1 - b0, kGrain, threaded, [&](std::size_t i) {
            rotateSampleFeatures(tables, &rotations[9 * i], samples.shDegree, &samples.targetF[(b0 + i) * stride]);
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
    const std::size_t cells = samples.cellCount();
    if (n < 2 || !samples.layoutConsistent() || samples.warpedPositions.size() != samples.restPositions.size())
        throw InputError("computeCellGradients: needs >= 2 samples per axis and warped positions for every cell");
    samples.cellGradient.resize(9 * cells);
    parallelFor(cells, kGrain, threaded, [&](std::size_t c) {
        cellGradientAt(samples.restPositions.data(), samples.warpedPositions.data(), samples.firstSampleOf(c),
                       samples.axisOf(c), n, &samples.cellGradient[9 * c]);
    });
}

} // namespace splatwarp
