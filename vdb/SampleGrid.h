#pragma once
/// @file SampleGrid.h
/// @brief The sampled radiance field (paper Sec. 3.2.1):
///        a sparse OpenVDB topology of rest-space cells of edge h, n^3 samples per active cell,
///        and the rest targets F, O at every sample. The OpenVDB grids stay behind a pimpl; callers
///        see the flat SampleSet.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/Device.h"
#include "core/GaussianCloud.h"
#include "core/SmallMath.h"
#include "field/CellIndexGrid.h"
#include "field/FeatureField.h"
#include "field/GaussianMath.h"
#include "field/SampleSet.h"

namespace splatwarp {

/// SampleGridOptions::samplesPerAxis meaning "auto" (autoSampleBudget decides n).
constexpr int kAutoSamplesPerAxis = 0;
/// The n that "auto" chooses from: at least the paper's 4, at most 8.
constexpr int kAutoSamplesMin = 4, kAutoSamplesMax = 8;
/// Samples "auto" may spend: 2^20. Denser samples fit the field the judge sees a little better
/// (train-1000 bend 0.595 -> 0.577 of Stage I from n = 4 to 8, mean of 16 judge seeds), and Stage
/// II's time and memory grow with them: from 2^22 to 2^20 guitar (n 6 -> 4) lost 1.8-2.6% on the
/// field judge for 2.5x less CPU time, train-1000 (8 -> 5) 0-4.6% for 2.2x, the demo (6 -> 4) 1%
/// (16.3 -> 10.1 s), and the stripes mesh (5 -> 4) kept its PSNR to 0.02 dB
/// (docs/lab/sample-budget.md). Models whose 4^3 lattice already holds this many keep n = 4.
constexpr std::size_t kAutoSampleBudget = std::size_t(1) << 20;

/// @brief Parameters of the sample grid (one options struct for the CLI, specs and tests).
struct SampleGridOptions {
    /// Cells along the largest extent of the model (the union of the Gaussians' unfiltered extent
    /// boxes); used when cellSize <= 0. The paper's resolution.
    int cells = 64;
    /// Explicit cell edge h in world units; > 0 overrides `cells`.
    float cellSize = 0.0f;
    /// n: samples per cell along each axis (n^3 per cell, spacing h/n); >= 2 so that a cell's
    /// corner samples span a volume for its deformation gradient. kAutoSamplesPerAxis: the
    /// densest n in [kAutoSamplesMin, kAutoSamplesMax] whose grid holds at most autoSampleBudget
    /// samples and fits maxMemoryBytes, counted on the cells of the n = kAutoSamplesMin lattice
    /// (options() then holds the n chosen).
    int samplesPerAxis = 4;
    std::size_t autoSampleBudget = kAutoSampleBudget; ///< for kAutoSamplesPerAxis
    /// A (sample, Gaussian) pair contributes only where alpha*G >= cutoff (1e-3 for thin structures).
    float cutoff = kDefaultCutoff;
    /// The rest targets use Mip-Splatting's isotropic 3D filter: variance lambdaLpf * spacing^2 is
    /// added to every covariance (0 = no filter).
    float lambdaLpf = kDefaultLambdaLpf;
    /// Run the parallel loops with oneTBB (false: serial, deterministic debugging).
    bool threaded = true;
    /// Where the rest targets are evaluated. The library default is Cpu (no GPU probe for tests
    /// and tools that do not ask); the CLI passes `--device` (default auto). Cuda looks the
    /// Gaussians' cells up in the NanoVDB index grid on the GPU; under Auto a GPU out-of-memory
    /// falls back to the CPU. Both give the same targets to float rounding (expf, summation).
    ResolvedDevice device;
    /// Refuse (InputError naming the flags and the estimate) a grid whose host memory, estimated
    /// from the cell count before the per-sample arrays are allocated, exceeds this (0 = no limit).
    std::size_t maxMemoryBytes = 0;
    /// Finer samples where the Gaussians are small (0: off, the uniform lattice): a cell whose
    /// Gaussians (those centred in it) have a median largest scale below fineBelow x h/n holds
    /// (2n)^3 samples, and its Gaussians' rest filter is lambda (h/2n)^2 (SampleSet::cellAxis).
    float fineBelow = 0.0f;
    /// With fineBelow: also refine the active neighbours (26) of each such cell, so the small
    /// Gaussians' footprints beyond their cell are sampled finely too.
    bool fineNeighbours = false;
    /// Host bytes per sample that the caller's later stages add (e.g. Stage II), counted in the estimate.
    std::size_t extraBytesPerSample = 0;
};

/// @brief Host bytes one active cell costs (its n^3 samples' positions, targets and indices, the
///        cell's coordinates, gradient and index-grid voxel), plus extraBytesPerSample per sample.
std::size_t sampleGridBytesPerCell(const SampleGridOptions& options, int shDegree);

/// @brief Counts and timings of a build (for progress lines, reports and the benchmark).
struct SampleGridStats {
    std::size_t cells = 0;          ///< active cells C
    std::size_t samples = 0;        ///< samples M = C n^3 + 7 n^3 per fine cell
    std::size_t fineCells = 0;      ///< cells with (2n)^3 samples (SampleGridOptions::fineBelow)
    std::size_t fineSamplesAdded = 0; ///< samples the fine cells add to the uniform lattice's C n^3
    std::size_t skippedCells = 0;   ///< cells with cellSkip = 1
    double topologyMs = 0.0;        ///< cell topology + index grid + sample placement
    double featuresMs = 0.0;        ///< rest targets F, O
    std::uint64_t pairsTested = 0;       ///< (sample, Gaussian) candidates the feature evaluation looked at
    std::uint64_t pairsContributing = 0; ///< pairs with alpha*G >= cutoff
    Device device = Device::Cpu;         ///< the device that evaluated the rest targets
};

/// @brief Rest-space sparse sample grid of a Gaussian model.
/// @details Cell (i,j,k) spans [i h, (i+1) h) x ... in world space; its sample (a,b,c),
///          0 <= a,b,c < n, sits at ((i n + a + 1/2) s, ...) with s = h/n, i.e. on the global
///          lattice index (i n + a, j n + b, k n + c). Cells are numbered in the (deterministic)
///          leaf order of the OpenVDB index grid; sample m of cell c is c n^3 + (a n + b) n + cc.
///          With fine cells (options.fineBelow) a fine cell holds the (2n)^3 samples of spacing
///          h/2n, octant by octant, from SampleSet::cellFirst[c] (SampleSet::firstSampleOf()).
class SampleGrid {
public:
    /// @brief Build the topology, the Int32 index grid, the rest samples and their targets.
    /// @throws InputError for an empty model, bad options or a model with zero extent.
    SampleGrid(const GaussianCloud& cloud, const SampleGridOptions& options = {});
    ~SampleGrid();
    SampleGrid(SampleGrid&&) noexcept;
    SampleGrid& operator=(SampleGrid&&) noexcept;

    const SampleGridOptions& options() const;
    const SampleGridStats& stats() const;
    /// @brief The flat view (warpedPositions = restPositions, cellGradient = identity until warped).
    const SampleSet& samples() const;
    /// @brief Mutable view, for warpSamples() (deform/SampleWarp.h).
    SampleSet& samples();
    /// @brief [N] index of the cell holding each Gaussian's centre (always active).
    const std::vector<std::int32_t>& gaussianCell() const;
    /// @brief [C,3] integer coordinates (i,j,k) of each cell.
    const std::vector<std::int32_t>& cellCoords() const;
    /// @brief The feature options the rest targets were evaluated with (cutoff, rest filter
    ///        lambda (h/n)^2; with fine cells their Gaussians' filter is lambda (h/2n)^2 instead).
    const FeatureOptions& targetOptions() const;
    /// @brief The Int32 index grid converted to NanoVDB (the index of each cell of cellCoords(),
    ///        background -1), for the GPU and other OpenVDB-free code (see field/CellTargetMath.h).
    CellIndexGrid nanoIndexGrid() const;

    struct Impl;
    /// @brief The OpenVDB side (vdb/ translation units only; opaque elsewhere).
    const Impl& impl() const { return *mImpl; }

private:
    std::unique_ptr<Impl> mImpl;
};

} // namespace splatwarp
