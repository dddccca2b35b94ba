#pragma once
/// @file EdSolver.h
/// @brief Embedded-deformation solve (Sumner et al. 2007): per-node affine A_j and translation
///        t_j minimising w_rot E_rot + w_reg E_reg + w_con E_con by Gauss-Newton.
#include <cstdint>
#include <vector>

#include "deform/DeformationGraph.h"
#include "deform/NodeTransforms.h"

namespace splatwarp {

/// @brief Options of the ED solve (Stage I). Positions are normalised internally by the largest
///        extent of the node bounding box, so the weights mean the same for any model scale.
struct EdOptions {
    double rotWeight = 1.0;      ///< E_rot: orthonormality of A's columns (Sumner et al.)
    double regWeight = 10.0;     ///< E_reg: neighbouring nodes agree on each other's positions
    double conWeight = 100.0;    ///< E_con: handle nodes reach their targets
    int maxIterations = 100;     ///< Gauss-Newton iterations at most (lastchance + twist.json needs 44)
    double relativeStep = 1e-3;  ///< converged when |step| <= relativeStep * (|x| + relativeStep). Measured
                                 ///< against 1e-7: energy within 3e-6 (stripes bend) / 5e-6 (donut bend)
                                 ///< relative, handle residual within 0.1%, 7 vs 18 / 9 vs 25 iterations
    bool threaded = true;        ///< TBB for the per-node work
};

/// @brief Which nodes are pinned and which have targets, [J] each.
struct EdConstraints {
    std::vector<std::uint8_t> fixed;      ///< 1: hard constraint A = I, t = 0 (removed from the unknowns)
    std::vector<std::uint8_t> hasTarget;  ///< 1: E_con pulls g_j + t_j to target[j] (ignored when fixed)
    std::vector<Vec3d> target;            ///< deformed node position wanted (world units)
    /// @brief No constraint on n nodes.
    static EdConstraints none(std::size_t n);
};

/// @brief Weighted energies (w * sum of squared residuals) in normalised units (see EdOptions).
struct EdEnergies {
    double rot = 0, reg = 0, con = 0;
    double total() const { return rot + reg + con; }
};

/// @brief What a solve did.
struct EdReport {
    int iterations = 0;        ///< Gauss-Newton iterations taken (one factorisation each)
    bool converged = false;    ///< relative step fell below EdOptions::relativeStep
    EdEnergies initial, final; ///< at the start (rest or warm start) and at the end
    std::size_t freeNodes = 0; ///< nodes that are unknowns
    double ms = 0;             ///< wall time
};

/// @brief Solve from the rest pose (or from warmStart, e.g. the previous solution of an edit).
///        The result depends only on the constraints, not on the path: solving twice equals once.
/// @throws InputError when the constraint arrays do not match the graph.
NodeTransforms solveEd(const DeformationGraph& graph, const EdConstraints& constraints, const EdOptions& options = {},
                       EdReport* report = nullptr, const NodeTransforms* warmStart = nullptr);

} // namespace splatwarp
