#pragma once
/// @file StageTwoCuda.h
/// @brief Stage II on the GPU: same inputs, semantics and report as optimiseStageTwo() (the
///        CPU path is the reference). No CUDA types here. Everything stays on the GPU for the
///        whole optimisation; the host reads back only counts at coverage rebuilds (to size
///        buffers), the energy at report iterations and the result at the end.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "stage2/Coverage.h"
#include "stage2/StageTwo.h"

namespace splatwarp::cuda {

/// @brief optimiseStageTwo() on the current CUDA device. The cloud is written only when the
///        run succeeds (onEval gets a copy), so a failed run can be repeated on the CPU.
/// @throws InputError as optimiseStageTwo(); DeviceMemoryError when a buffer does not fit
///         (the message names it); Error for any other CUDA failure
StageTwoReport optimiseStageTwoCuda(GaussianCloud& cloud, const SampleSet& samples,
                                    const std::vector<std::uint8_t>& moving,
                                    const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options,
                                    const std::function<void(int, const GaussianCloud&)>& onEval = {},
                                    int evalEvery = 0);

/// @brief What the GPU computed in one forward and backward pass at the start parameters
///        (iteration 0, fresh coverage): for the parity tests. S used samples, G moving
///        Gaussians, P coverage pairs, stride = 3 (degree+1)^2.
struct StageTwoCudaProbe {
    std::vector<std::uint32_t> used;      ///< [S] sample indices used (cell not skipped)
    std::vector<std::uint32_t> moving;    ///< [G] moving Gaussian indices
    std::vector<float> boxLo, boxHi;      ///< [G,3] padded coverage boxes
    std::vector<CoverageSlabs> slabs;     ///< [G] coverage slabs
    std::vector<std::uint32_t> sampleOffsets, sampleItems;     ///< [S+1], [P] coverage per sample (box index k)
    std::vector<std::uint32_t> gaussianOffsets, gaussianItems; ///< [G+1], [P] coverage per box (sample index)
    std::vector<float> features;          ///< [S,stride] F (static + moving Gaussians)
    std::vector<float> opacity;           ///< [S] O
    std::vector<float> gradF;             ///< [S,stride] dE/dF
    std::vector<float> gradO;             ///< [S] dE/dO
    std::vector<float> grad;              ///< [G,11+stride] dE/d(mean 3, rotation 4, logScale 3, logit, SH)
    StageTwoEnergy energy;                ///< energy terms of this forward pass
    std::uint64_t pairs = 0;              ///< counted pairs (alpha G >= cutoff)
};

/// @brief Run the probe (see StageTwoCudaProbe); the cloud is not changed.
StageTwoCudaProbe probeStageTwoCuda(const GaussianCloud& cloud, const SampleSet& samples,
                                    const std::vector<std::uint8_t>& moving,
                                    const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options);

/// @brief Resources and theoretical occupancy of one Stage II kernel (instantiation) on the
///        current device at the block size it is launched with.
struct KernelOccupancy {
    std::string name;            ///< e.g. "backwardKernel<48>"
    int blockSize = 0;           ///< threads per block at launch
    int registers = 0;           ///< per thread (cudaFuncAttributes::numRegs)
    std::size_t localBytes = 0;  ///< local memory per thread: spills and stack (localSizeBytes)
    std::size_t sharedBytes = 0; ///< static shared memory per block
    int blocksPerSm = 0;         ///< cudaOccupancyMaxActiveBlocksPerMultiprocessor at blockSize
    double occupancy = 0;        ///< blocksPerSm * blockSize / maxThreadsPerMultiProcessor
};

/// @brief Every kernel a Stage II run launches (the per-stride ones at strides 3, 12, 27, 48,
///        the coverage bins' too), measured on the current device.
/// @throws Error for a CUDA failure (no device)
std::vector<KernelOccupancy> stageTwoKernelOccupancy();

} // namespace splatwarp::cuda
