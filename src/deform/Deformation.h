#pragma once
/// @file Deformation.h
/// @brief From a rest model and a spec to solved node transforms: graph, handle resolution, ED
///        solve. The one call used by Stage I, Stage II and `to-vdb --spec`.
#include <cstdint>
#include <vector>

#include "core/GaussianCloud.h"
#include "deform/DeformSpec.h"
#include "deform/DeformationGraph.h"
#include "deform/EdSolver.h"
#include "deform/NodeTransforms.h"

namespace splatwarp {

/// @brief A node selected by two handles: the later one wins.
struct NodeReassignment {
    int node = 0, fromHandle = 0, toHandle = 0;
};

/// @brief The spec's handles applied to a graph: constraints for the solver.
struct HandleResolution {
    EdConstraints constraints;                    ///< fixed / targets per node (world units)
    std::vector<int> handleOf;                    ///< [J] handle index that owns the node, -1 free
    std::vector<std::size_t> nodesPerHandle;      ///< [H] nodes each handle finally owns
    std::vector<NodeReassignment> reassignments;  ///< nodes taken over by a later handle
};

/// @brief Select nodes and compute targets. "bbox" units use the centre bounding box of rest.
/// @throws InputError naming the spec and handle: empty selection, node index out of range.
HandleResolution resolveHandles(const DeformSpec& spec, const DeformationGraph& graph, const GaussianCloud& rest);

/// @brief What solveDeformation() did (for report.json).
struct DeformationReport {
    EdReport solver;
    std::size_t fixedNodes = 0, targetNodes = 0, freeNodes = 0;
    double residualMax = 0, residualMean = 0;     ///< |g_j + t_j - target_j| over target nodes, world units
    std::vector<std::size_t> nodesPerHandle;
    std::vector<NodeReassignment> reassignments;
    double graphMs = 0, resolveMs = 0;            ///< graph build (0 when given) and handle resolution
};

/// @brief A solved deformation.
struct Deformation {
    DeformationGraph graph;
    NodeTransforms transforms;
    std::vector<std::uint8_t> nodeMoving; ///< [J] 0 for fixed nodes and nodes left exactly at identity
    HandleResolution handles;
    DeformationReport report;
};

/// @brief Build the graph from spec.graph, resolve the handles, solve ED from the rest pose.
Deformation solveDeformation(const GaussianCloud& rest, const DeformSpec& spec, const EdOptions& options = {});

/// @brief Same on an existing graph (repeated edits of one model); warmStart as in solveEd().
Deformation solveDeformation(const DeformationGraph& graph, const GaussianCloud& rest, const DeformSpec& spec,
                             const EdOptions& options = {}, const NodeTransforms* warmStart = nullptr);

} // namespace splatwarp
