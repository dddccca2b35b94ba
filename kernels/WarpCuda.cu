#include "kernels/WarpCuda.h"

#include <algorithm>
#include <vector>

#include "kernels/CudaLaunch.cuh"
#include "kernels/DeviceBuffer.h"
#include "deform/SkinWeightMath.h"
#include "deform/WarpMath.h"

namespace splatwarp::cuda {
namespace {

/// Points skinned per batch: bounds the device weight arrays ([batch,k] nodes and weights, 8 k
/// bytes per point) and rotations.
constexpr std::size_t kBatch = std::size_t(1) << 20;

/// One thread per point of a batch (arrays batch-relative; rotations may be null).
__global__ void warpPointsKernel(std::size_t n, const NodeAffine* affines, const std::int32_t* nodes,
                                 const float* weights, std::size_t k, const float* points, float* warped,
                                 float* rotations)
{
    const std::size_t p = globalIndex();
    if (p >= n) return;
    warpPoint(affines, nodes, weights, k, points, p, warped, rotations);
}

/// One thread per sample of a batch: warpPointsKernel + the target SH rotation (shDegree > 0).
__global__ void warpSamplesKernel(std::size_t n, const NodeAffine* affines, const std::int32_t* nodes,
                                  const float* weights, std::size_t k, const float* points, float* warped,
                                  float* rotations, const ShRotationTables* tables, int shDegree, std::size_t stride,
                                  float* features)
{
    const std::size_t p = globalIndex();
    if (p >= n) return;
    warpPoint(affines, nodes, weights, k, points, p, warped, rotations);
    rotateSampleFeatures(*tables, rotations + 9 * p, shDegree, features + p * stride);
}

/// One thread per cell: F_k from the warped corner samples; first [C] and axis [C] give each
/// cell's samples (SampleSet::cellFirst, cellAxis), or are null for the uniform lattice.
__global__ void cellGradientKernel(std::size_t cells, const float* rest, const float* warped, int n,
                                   const std::uint64_t* first, const std::uint8_t* axis, float* out)
{
    const std::size_t c = globalIndex();
    if (c >= cells) return;
    if (first)
        cellGradientAt(rest, warped, std::size_t(first[c]), int(axis[c]), n, out + 9 * c);
    else
        cellGradient(rest, warped, n, c, out + 9 * c);
}

/// One thread per point of a batch: brute-force k nearest of the J nodes and their weights.
__global__ void skinWeightsKernel(std::size_t n, const double* graphNodes, std::size_t j, std::size_t k,
                                  const float* points, std::int32_t* nodes, float* weights)
{
    const std::size_t p = globalIndex();
    if (p >= n) return;
    skinWeightsBrute(graphNodes, j, k, points, p, nodes, weights);
}

/// The graph nodes [J,3] on the device, for skinWeightsKernel.
struct DeviceGraph {
    DeviceBuffer<double> nodes{"graph nodes"};
    std::size_t j = 0, k = 0;
    DeviceGraph(const DeformationGraph& graph, cudaStream_t st)
    {
        j = graph.nodeCount();
        k = std::min<std::size_t>(std::size_t(graph.k()), j);
        if (j == 0 || k == 0) throw InputError("skin weights: the graph has no nodes");
        if (k > kMaxSkinK) throw InputError(msg("skin weights on the GPU: k ", k, " is above ", kMaxSkinK));
        std::vector<double> flat(3 * j);
        for (std::size_t n = 0; n < j; ++n)
            for (int a = 0; a < 3; ++a) flat[3 * n + std::size_t(a)] = graph.nodes()[n][a];
        nodes.upload(flat, st);
        SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(st)); // flat dies here
    }
    /// Weights of device points [n,3] into nodes/weights ([n,k], resized); asynchronous.
    void weigh(const float* points, std::size_t n, DeviceBuffer<std::int32_t>& outNodes, DeviceBuffer<float>& outWeights,
               cudaStream_t st) const
    {
        outNodes.resize(n * k);
        outWeights.resize(n * k);
        launch("skinWeightsKernel", skinWeightsKernel, n, st, n, nodes.data(), j, k, points, outNodes.data(),
               outWeights.data());
    }
};

/// Copy host data to a device buffer of n elements.
template <typename T>
void uploadRaw(DeviceBuffer<T>& to, const T* from, std::size_t n, cudaStream_t st)
{
    to.resize(n);
    if (n) SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(to.data(), from, n * sizeof(T), cudaMemcpyHostToDevice, st));
}

} // namespace

SkinWeights skinWeightsCuda(const DeformationGraph& graph, const float* points, std::size_t count)
{
    StreamHolder stream;
    const cudaStream_t st = stream.stream;
    const DeviceGraph dGraph(graph, st);
    SkinWeights w;
    w.k = int(dGraph.k);
    if (count == 0) return w;
    DeviceBuffer<float> dPoints("skin-weight points");
    uploadRaw(dPoints, points, 3 * count, st);
    DeviceBuffer<std::int32_t> dNodes("skin-weight nodes");
    DeviceBuffer<float> dWeights("skin weights");
    dGraph.weigh(dPoints.data(), count, dNodes, dWeights, st);
    w.nodes.resize(count * dGraph.k);
    w.weights.resize(count * dGraph.k);
    dNodes.download(w.nodes.data(), w.nodes.size(), st);
    dWeights.download(w.weights.data(), w.weights.size(), st);
    return w;
}

void warpPointsCuda(const DeformationGraph& graph, const NodeTransforms& transforms, const float* points,
                    std::size_t count, float* warped, float* rotations, bool /*threaded: the CPU does nothing here*/)
{
    if (transforms.size() != graph.nodeCount())
        throw InputError(msg("warpPoints: ", transforms.size(), " node transforms for ", graph.nodeCount(), " nodes"));
    if (count == 0) return;
    StreamHolder stream;
    const cudaStream_t st = stream.stream;
    const DeviceGraph dGraph(graph, st);
    const std::vector<NodeAffine> affines = nodeAffines(graph, transforms);
    DeviceBuffer<NodeAffine> dAffines("warp node transforms");
    dAffines.upload(affines, st);
    DeviceBuffer<float> dPoints("warp points"), dWarped(3 * count, "warped points"),
        dRotations(rotations ? 9 * count : 0, "warp rotations");
    uploadRaw(dPoints, points, 3 * count, st);
    DeviceBuffer<std::int32_t> dNodes("skin-weight nodes");
    DeviceBuffer<float> dWeights("skin weights");
    for (std::size_t b0 = 0; b0 < count; b0 += kBatch) {
        const std::size_t b1 = std::min(count, b0 + kBatch);
        dGraph.weigh(dPoints.data() + 3 * b0, b1 - b0, dNodes, dWeights, st);
        const std::size_t k = dGraph.k;
        launch("warpPointsKernel", warpPointsKernel, b1 - b0, st, b1 - b0, (const NodeAffine*)dAffines.data(),
               (const std::int32_t*)dNodes.data(), (const float*)dWeights.data(), k,
               (const float*)dPoints.data() + 3 * b0, dWarped.data() + 3 * b0,
               rotations ? dRotations.data() + 9 * b0 : nullptr);
    }
    // The host affines must live until the upload ran; the downloads below wait for everything.
    dWarped.download(warped, 3 * count, st);
    if (rotations) dRotations.download(rotations, 9 * count, st);
}

void warpSamplesCuda(SampleSet& samples, const DeformationGraph& graph, const NodeTransforms& transforms,
                     bool /*threaded: the CPU does nothing here*/)
{
    checkWarpSamples(samples, graph, transforms);
    const std::size_t m = samples.sampleCount();
    const int n = samples.samplesPerAxis;
    const std::size_t cells = samples.cellCount();
    if (n < 2 || !samples.layoutConsistent())
        throw InputError("computeCellGradients: needs >= 2 samples per axis and warped positions for every cell");
    const std::size_t stride = std::size_t(samples.featureStride());
    const bool rotate = samples.shDegree > 0;
    StreamHolder stream;
    const cudaStream_t st = stream.stream;
    const DeviceGraph dGraph(graph, st);
    const std::vector<NodeAffine> affines = nodeAffines(graph, transforms);
    const std::vector<ShRotationTables> tables{shRotationTables()};
    DeviceBuffer<NodeAffine> dAffines("warp node transforms");
    DeviceBuffer<ShRotationTables> dTables("SH rotation tables");
    dAffines.upload(affines, st);
    dTables.upload(tables, st);
    DeviceBuffer<float> dRest("sample rest positions"), dWarped(3 * m, "warped sample positions"),
        dFeatures("sample target features"), dGradient(9 * cells, "cell gradients"),
        dRotations(rotate ? 9 * std::min(m, kBatch) : 0, "sample rotations");
    dRest.upload(samples.restPositions, st);
    if (rotate) dFeatures.upload(samples.targetF, st);
    DeviceBuffer<std::uint64_t> dCellFirst("cell first samples");
    DeviceBuffer<std::uint8_t> dCellAxis("cell samples per axis");
    if (!samples.uniform()) {
        dCellFirst.upload(samples.cellFirst, st);
        dCellAxis.upload(samples.cellAxis, st);
    }
    DeviceBuffer<std::int32_t> dNodes("skin-weight nodes");
    DeviceBuffer<float> dWeights("skin weights");
    for (std::size_t b0 = 0; b0 < m; b0 += kBatch) {
        const std::size_t b1 = std::min(m, b0 + kBatch), nb = b1 - b0;
        dGraph.weigh(dRest.data() + 3 * b0, nb, dNodes, dWeights, st);
        const std::size_t k = dGraph.k;
        const NodeAffine* a = dAffines.data();
        const std::int32_t* nodes = dNodes.data();
        const float* w = dWeights.data();
        const float* points = dRest.data() + 3 * b0;
        if (rotate)
            launch("warpSamplesKernel", warpSamplesKernel, nb, st, nb, a, nodes, w, k, points, dWarped.data() + 3 * b0,
                   dRotations.data(), (const ShRotationTables*)dTables.data(), samples.shDegree, stride,
                   dFeatures.data() + b0 * stride);
        else
            launch("warpPointsKernel", warpPointsKernel, nb, st, nb, a, nodes, w, k, points, dWarped.data() + 3 * b0,
                   (float*)nullptr);
        // The weight and rotation buffers are reused by the next batch: stream order keeps them apart.
    }
    launch("cellGradientKernel", cellGradientKernel, cells, st, cells, (const float*)dRest.data(),
           (const float*)dWarped.data(), n, samples.uniform() ? nullptr : (const std::uint64_t*)dCellFirst.data(),
           samples.uniform() ? nullptr : (const std::uint8_t*)dCellAxis.data(), dGradient.data());
    // Download everything before touching the samples, so a failure leaves them as they were.
    std::vector<float> warped(3 * m), features, gradient(9 * cells);
    dWarped.download(warped.data(), warped.size(), st);
    if (rotate) {
        features.resize(samples.targetF.size());
        dFeatures.download(features.data(), features.size(), st);
    }
    dGradient.download(gradient.data(), gradient.size(), st);
    samples.warpedPositions = std::move(warped);
    if (rotate) samples.targetF = std::move(features);
    samples.cellGradient = std::move(gradient);
}

} // namespace splatwarp::cuda
