#include "kernels/StageOneCuda.h"

#include <algorithm>

#include "kernels/CudaLaunch.cuh"
#include "kernels/DeviceBuffer.h"
#include "deform/StageOneMath.h"

namespace splatwarp::cuda {
namespace {

/// One thread per Gaussian: the shared per-element update (deform/StageOneMath.h).
__global__ void stageOneKernel(std::size_t n, StageOneInputs in, StageOneParams params, StageOneOutputs out)
{
    const std::size_t i = globalIndex();
    if (i >= n) return;
    stageOneUpdate(in, params, i, out);
}

class StageOneCuda final : public StageOneEngine {
public:
    StageOneCuda(const GaussianCloud& rest, const StageOneRig& rig, std::size_t nodeCount, const StageOneOptions& o)
        : mRest(rest), mNodeCount(nodeCount), mParams(stageOneParams(o, rig.extent))
    {
        const cudaStream_t st = mStream.stream;
        mMeans.upload(rest.means, st);
        mRotations.upload(rest.rotations, st);
        mLogScales.upload(rest.logScales, st);
        mSh.upload(rest.sh, st);
        mNodes.upload(rig.weights.nodes, st);
        mWeights.upload(rig.weights.weights, st);
        const std::vector<ShRotationTables> tables{shRotationTables()};
        mTables.upload(tables, st);
        mOutMeans.resize(rest.means.size());
        mOutRotations.resize(rest.rotations.size());
        mOutLogScales.resize(rest.logScales.size());
        mOutSh.resize(rest.sh.size());
        mMoving.resize(rest.size());
        mAffines.resize(nodeCount);
        mNodeMoving.resize(nodeCount);
        mK = std::size_t(rig.weights.k);
        // The uploads read host vectors (tables dies here): wait for them before returning.
        SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(st));
    }

    StageOneResult apply(const std::vector<NodeAffine>& affines, const std::vector<std::uint8_t>& nodeMoving) override
    {
        if (affines.size() != mNodeCount || nodeMoving.size() != mNodeCount)
            throw InputError(msg("Stage I (CUDA): ", affines.size(), " transforms / ", nodeMoving.size(),
                                 " moving flags for ", mNodeCount, " nodes"));
        const cudaStream_t st = mStream.stream;
        mAffines.upload(affines, st);
        mNodeMoving.upload(nodeMoving, st);
        // Static Gaussians keep their rest values: start the outputs from the rest model.
        copyDevice(mOutMeans, mMeans, st);
        copyDevice(mOutRotations, mRotations, st);
        copyDevice(mOutLogScales, mLogScales, st);
        copyDevice(mOutSh, mSh, st);
        StageOneInputs in;
        in.means = mMeans.data();
        in.rotations = mRotations.data();
        in.logScales = mLogScales.data();
        in.nodes = mNodes.data();
        in.weights = mWeights.data();
        in.k = mK;
        in.affines = mAffines.data();
        in.nodeMoving = mNodeMoving.data();
        in.shTables = mTables.data();
        in.shDegree = mRest.shDegree;
        StageOneOutputs out;
        out.means = mOutMeans.data();
        out.rotations = mOutRotations.data();
        out.logScales = mOutLogScales.data();
        out.sh = mOutSh.data();
        out.moving = mMoving.data();
        const std::size_t n = mRest.size();
        launch("stageOneKernel", stageOneKernel, n, st, n, in, mParams, out);

        StageOneResult res;
        res.deformed = mRest; // opacities and metadata; the updated arrays are overwritten below
        res.moving.assign(n, 0);
        // Each download waits for its copy; the last one also orders after the kernel.
        mOutMeans.download(res.deformed.means.data(), res.deformed.means.size(), st);
        mOutRotations.download(res.deformed.rotations.data(), res.deformed.rotations.size(), st);
        mOutLogScales.download(res.deformed.logScales.data(), res.deformed.logScales.size(), st);
        mOutSh.download(res.deformed.sh.data(), res.deformed.sh.size(), st);
        mMoving.download(res.moving.data(), n, st);
        res.movingCount = std::size_t(std::count(res.moving.begin(), res.moving.end(), std::uint8_t(1)));
        return res;
    }

private:
    template <typename T>
    static void copyDevice(DeviceBuffer<T>& to, const DeviceBuffer<T>& from, cudaStream_t st)
    {
        if (from.size() == 0) return;
        SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(to.data(), from.data(), from.bytes(), cudaMemcpyDeviceToDevice, st));
    }

    const GaussianCloud& mRest;
    std::size_t mNodeCount;
    StageOneParams mParams;
    std::size_t mK = 0;
    StreamHolder mStream;
    DeviceBuffer<float> mMeans{"Stage I rest means"}, mRotations{"Stage I rest rotations"},
        mLogScales{"Stage I rest log-scales"}, mSh{"Stage I rest SH"};
    DeviceBuffer<std::int32_t> mNodes{"Stage I skin-weight nodes"};
    DeviceBuffer<float> mWeights{"Stage I skin weights"};
    DeviceBuffer<ShRotationTables> mTables{"SH rotation tables"};
    DeviceBuffer<float> mOutMeans{"Stage I means"}, mOutRotations{"Stage I rotations"},
        mOutLogScales{"Stage I log-scales"}, mOutSh{"Stage I SH"};
    DeviceBuffer<std::uint8_t> mMoving{"Stage I moving flags"};
    DeviceBuffer<NodeAffine> mAffines{"Stage I node transforms"};
    DeviceBuffer<std::uint8_t> mNodeMoving{"Stage I node moving flags"};
};

} // namespace

std::unique_ptr<StageOneEngine> makeStageOneCuda(const GaussianCloud& rest, const StageOneRig& rig,
                                                 std::size_t nodeCount, const StageOneOptions& options)
{
    return std::make_unique<StageOneCuda>(rest, rig, nodeCount, options);
}

} // namespace splatwarp::cuda
