#pragma once
/// @file StageOne.h
/// @brief Stage I: move every Gaussian with the embedded deformation. Six endpoints at +-2 sigma
///        along its axes are skinned, M = (P Q^T)(Q Q^T)^-1 is split by polar decomposition M = R S,
///        and mean, rotation, scales and SH follow (choices: docs/design-notes.md).
#include <cstdint>
#include <vector>

#include "core/Device.h"
#include "core/GaussianCloud.h"
#include "deform/Deformation.h"
#include "deform/DeformationGraph.h"
#include "deform/NodeTransforms.h"

namespace splatwarp {

/// @brief Options of Stage I.
/// @brief How a moving Gaussian's shape follows M, the affine map fitted to its skinned endpoints.
enum class StageOneShape {
    /// Covariance M Sigma M^T: exact to first order, so shear off the Gaussian's axes and a flat
    /// Gaussian's normal (which turns by M^-T, not by M's rotation) follow. Judged on the shared
    /// models it lowers Stage I's error by a quarter to a third (docs/lab/fidelity-study.md).
    Affine,
    /// The paper's: rotation R R0 from M = R S, each rest axis scaled by S's stretch along it.
    Polar,
};

struct StageOneOptions {
    StageOneShape shape = StageOneShape::Affine;
    double endpointSigmas = 2.0;     ///< endpoints at +-endpointSigmas * sigma per axis (paper: 2)
    double flatEpsilon = 1e-3;       ///< sigma = scale + flatEpsilon * largest scale: flat Gaussians keep a frame
    double absoluteEpsilon = 1e-6;   ///< ... + absoluteEpsilon * model extent: near-zero Gaussians too
    double minStretch = 1e-6;        ///< lower bound of the stretch along an axis (keeps log-scales finite)
    bool threaded = true;
    /// Where StageOneUpdater (deform/StageOneDevice.h) runs the update; applyStageOneCpu() is
    /// always the CPU.
    ResolvedDevice device;
};

/// @brief Per-model precomputation: the 7 skinned points of every Gaussian (centre, then the
///        endpoints +x,-x,+y,-y,+z,-z of its own axes) and their skin weights.
struct StageOneRig {
    std::vector<float> points;   ///< [N*7,3] rest positions
    SkinWeights weights;         ///< [N*7,k]
    double extent = 1.0;         ///< largest extent of the centre bounding box
    std::size_t size() const { return points.size() / 21; }
};

/// @brief Timings of a Stage I run, ms.
struct StageOneTimings {
    double rigMs = 0;     ///< endpoints and weights (0 when a rig was given)
    double updateMs = 0;  ///< per-Gaussian update
};

/// @brief Deformed model and which Gaussians moved.
struct StageOneResult {
    GaussianCloud deformed;            ///< static Gaussians are bit-exact copies of the rest model
    std::vector<std::uint8_t> moving;  ///< [N] 1 if any of its 7 points has weight on a moving node
    std::size_t movingCount = 0;
    StageOneTimings timings;
    Device device = Device::Cpu;       ///< where the update ran
};

struct StageOneParams; // deform/StageOneMath.h
struct StageOneInputs; // deform/StageOneMath.h
struct NodeAffine;     // deform/SkinningMath.h

/// @brief The update's read-only inputs on a rest model, its rig and node affines [J] (arrays
///        borrowed, not copied); the caller sets nodeMoving and the SH tables where it needs them.
StageOneInputs stageOneInputs(const GaussianCloud& rest, const StageOneRig& rig, const NodeAffine* affines);

/// @brief The options and model extent as the per-Gaussian update takes them.
StageOneParams stageOneParams(const StageOneOptions& options, double extent);

/// @brief Check that rig, transforms and moving flags fit the model and graph.
/// @throws InputError naming the mismatch
void checkStageOneInputs(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                         const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving);

/// @brief Endpoints and weights for a rest model on a graph (once per model and graph).
StageOneRig prepareStageOne(const GaussianCloud& rest, const DeformationGraph& graph, const StageOneOptions& options = {});

/// @brief Apply node transforms to every Gaussian on the CPU (the reference of every device;
///        StageOneUpdater, deform/StageOneDevice.h, picks the device). nodeMoving [J]: 0 for nodes
///        at identity.
StageOneResult applyStageOneCpu(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                             const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving,
                             const StageOneOptions& options = {});

/// @brief Stage I for a live preview (the editor's drag), on the CPU, in float: applyStageOneCpu()'s
///        means and covariances to float's rounding (the rotations and log-scales may name the axes
///        in another order), written into `preview`, and no SH rotation (a preview shows the DC
///        colour); 2.5x faster (deform/StageOnePreview.cpp). `preview` is a copy of rest at SH
///        degree 0 (opacities and DC as rest: withShDegree(rest, 0)); Gaussians that do not move get
///        their rest values back.
/// @returns the moving Gaussians' count
std::size_t applyStageOnePreview(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                                 const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving,
                                 const StageOneOptions& options, GaussianCloud& preview);

} // namespace splatwarp
