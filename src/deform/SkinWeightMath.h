#pragma once
/// @file SkinWeightMath.h
/// @brief Skin weights of one point, host/device: the weight formula of
///        DeformationGraph::skinWeights() (one source of truth for the CPU and the GPU) and a
///        brute-force k-nearest search over the J graph nodes for the GPU (J is a few hundred).
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "core/HostDevice.h"

namespace splatwarp {

/// Largest k the brute-force search supports (the spec and CLI accept k in 1..64).
constexpr std::size_t kMaxSkinK = 64;

/// @brief Weights w_i = (1 - d_i / d_{k+1})^2, normalised, from the squared distances of the
///        `query` nearest nodes, nearest first (query = k + 1, or k when the graph has only k nodes).
/// @details Degenerate cases: with query == k (J <= k nodes) d_{k+1} is taken as twice the farthest
///          node's distance; when every weight would be zero (d_{k+1} == 0 or all k+1 nodes
///          equidistant) the weights are uniform 1/k. scratch: [k] doubles.
SPLATWARP_HOST_DEVICE void skinWeightsFromDistances(const double* d2, std::size_t query, std::size_t k,
                                                    double* scratch, float* weights)
{
    const double dNext = query > k ? std::sqrt(d2[k]) : 2.0 * std::sqrt(d2[k - 1]);
    double sum = 0.0;
    for (std::size_t i = 0; i < k; ++i) {
        const double t = dNext > 0.0 ? 1.0 - std::sqrt(d2[i]) / dNext : 0.0;
        scratch[i] = t > 0.0 ? t * t : 0.0;
        sum += scratch[i];
    }
    // d_{k+1} == 0 or all k+1 nodes equidistant: no preference, share equally.
    const bool uniform = !(sum > 0.0);
    for (std::size_t i = 0; i < k; ++i) weights[i] = float(uniform ? 1.0 / double(k) : scratch[i] / sum);
}

/// @brief Node n at squared distance d into the `found` nearest so far (idx, d2 sorted by distance
///        then node, nearest first, at most `query`), so the list is the same in any insertion
///        order (an equal distance: the lower node first); dropped when it would come after the
///        last of a full list.
SPLATWARP_HOST_DEVICE void insertNearest(double d, std::int32_t n, std::size_t query, std::size_t& found,
                                         std::int32_t* idx, double* d2)
{
    const auto before = [&](std::size_t i) { return d < d2[i] || (d == d2[i] && n < idx[i]); };
    if (found == query && !before(query - 1)) return;
    std::size_t at = found < query ? found : query - 1;
    while (at > 0 && before(at - 1)) {
        d2[at] = d2[at - 1];
        idx[at] = idx[at - 1];
        --at;
    }
    d2[at] = d;
    idx[at] = n;
    if (found < query) ++found;
}

/// @brief The `query` nearest of J nodes [J,3] to q, nearest first, by brute force (insertion into
///        a sorted list). Exact ties in distance go to the lower node index (nanoflann, on the
///        CPU, may order exact ties differently). query <= J and query <= kMaxSkinK + 1.
SPLATWARP_HOST_DEVICE void nearestNodesBrute(const double* nodes, std::size_t j, const double* q, std::size_t query,
                                             std::int32_t* idx, double* d2)
{
    std::size_t found = 0;
    for (std::size_t n = 0; n < j; ++n) {
        const double dx = nodes[3 * n] - q[0], dy = nodes[3 * n + 1] - q[1], dz = nodes[3 * n + 2] - q[2];
        insertNearest(dx * dx + dy * dy + dz * dz, std::int32_t(n), query, found, idx, d2);
    }
}

/// @brief Skin weights of point p of points [P,3] on the min(k, J) nearest of J nodes [J,3]:
///        nodes [P,k] and weights [P,k] rows p (k <= kMaxSkinK, J >= 1).
SPLATWARP_HOST_DEVICE void skinWeightsBrute(const double* nodes, std::size_t j, std::size_t k, const float* points,
                                            std::size_t p, std::int32_t* outNodes, float* outWeights)
{
    const std::size_t query = k + 1 < j ? k + 1 : j;
    std::int32_t idx[kMaxSkinK + 1];
    double d2[kMaxSkinK + 1], scratch[kMaxSkinK];
    const double q[3] = {points[3 * p], points[3 * p + 1], points[3 * p + 2]};
    nearestNodesBrute(nodes, j, q, query, idx, d2);
    skinWeightsFromDistances(d2, query, k, scratch, outWeights + p * k);
    for (std::size_t i = 0; i < k; ++i) outNodes[p * k + i] = idx[i];
}

} // namespace splatwarp
