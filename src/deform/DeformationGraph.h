#pragma once
/// @file DeformationGraph.h
/// @brief The embedded-deformation graph (Sumner et al. 2007): nodes by farthest-point sampling
///        over the Gaussian centres, edges to the k nearest nodes, and skin weights of any point
///        set on its k nearest nodes.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/GaussianCloud.h"
#include "core/SmallMath.h"

namespace splatwarp {

/// @brief Options of the deformation graph (also the "graph" block of a deformation spec).
struct GraphOptions {
    int nodes = 256;         ///< node count (fewer when the model has fewer distinct centres)
    int k = 8;               ///< nearest nodes per point and graph edges per node (10 for thin long shapes)
    std::uint32_t seed = 0;  ///< picks the first FPS node; the rest is deterministic
};

/// @brief Skin weights of P points on their k nearest nodes.
struct SkinWeights {
    int k = 0;                         ///< nodes per point: min(graph k, node count)
    std::vector<std::int32_t> nodes;   ///< [P,k] node indices, nearest first
    std::vector<float> weights;        ///< [P,k] w_j = (1 - d_j/d_{k+1})^2 normalised; >= 0, sum 1
    /// @brief Number of points P.
    std::size_t size() const { return k > 0 ? nodes.size() / std::size_t(k) : 0; }
};

namespace detail {
struct NodeIndex; // kd-tree over the node positions (nanoflann stays inside the .cpp)
}

/// @brief Nodes g_j (rest positions), their graph edges, and a kd-tree for skin weights.
class DeformationGraph {
public:
    DeformationGraph();
    ~DeformationGraph();
    DeformationGraph(const DeformationGraph&);
    DeformationGraph(DeformationGraph&&) noexcept;
    DeformationGraph& operator=(const DeformationGraph&);
    DeformationGraph& operator=(DeformationGraph&&) noexcept;

    /// @brief Farthest-point sampling over the Gaussian centres (deterministic for a seed; ties go
    ///        to the lowest index), edges to the k nearest other nodes.
    /// @note  Stops early when every remaining centre coincides with a node (duplicates, or fewer
    ///        centres than options.nodes), so nodeCount() may be smaller than options.nodes.
    /// @throws InputError for an empty cloud or options out of range.
    static DeformationGraph build(const GaussianCloud& cloud, const GraphOptions& options, bool threaded = true);
    /// @brief A graph from given node positions (tests, and callers with their own sampling).
    static DeformationGraph fromNodes(std::vector<Vec3d> nodes, int k);

    std::size_t nodeCount() const { return mNodes.size(); }
    /// @brief Rest positions g_j, [J].
    const std::vector<Vec3d>& nodes() const { return mNodes; }
    /// @brief Graph edges of node j: its min(k, J-1) nearest other nodes, nearest first.
    const std::vector<std::int32_t>& neighbours(std::size_t j) const { return mNeighbours[j]; }
    int k() const { return mK; }

    /// @brief Skin weights for any point set (Gaussian endpoints, field samples).
    /// @param points [P,3] positions in the rest space of the graph
    /// @note  Degenerate cases: with J <= k nodes, d_{k+1} is taken as twice the farthest node's
    ///        distance; when every weight would be zero (d_{k+1} == 0 or all distances equal),
    ///        the weights are uniform over the k nearest nodes.
    SkinWeights skinWeights(const float* points, std::size_t count, bool threaded = true) const;

private:
    void buildIndex();

    std::vector<Vec3d> mNodes;
    std::vector<std::vector<std::int32_t>> mNeighbours;
    int mK = 0;
    std::shared_ptr<const detail::NodeIndex> mIndex; // immutable, so copies may share it
};

} // namespace splatwarp
