#include "deform/DeformationGraph.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <nanoflann.hpp>
#include <random>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "core/Error.h"
#include "core/MortonOrder.h"
#include "core/ParallelFor.h"
#include "core/Simd.h"
#include "deform/SkinWeightMath.h"

namespace splatwarp {

namespace detail {

/// nanoflann dataset adaptor over an owned copy of the node positions.
struct NodeCloud {
    std::vector<double> xyz; // [J,3]
    std::size_t kdtree_get_point_count() const { return xyz.size() / 3; }
    double kdtree_get_pt(std::size_t i, std::size_t dim) const { return xyz[3 * i + dim]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const { return false; }
};

using NodeTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, NodeCloud>, NodeCloud, 3, std::int32_t>;

struct NodeIndex {
    NodeCloud cloud;
    std::unique_ptr<NodeTree> tree;

    /// Up to n nearest nodes of q, nearest first; returns how many were found.
    std::size_t nearest(const double* q, std::size_t n, std::int32_t* idx, double* dist2) const
    {
        return tree->knnSearch(q, n, idx, dist2);
    }
};

} // namespace detail

namespace {

/// One FPS round: fold the newest node into the running minimum distances and find the farthest
/// point. Ties go to the lowest index so serial and parallel runs pick the same nodes.
struct FarthestOp {
    const float* points;
    float* minDist2;
    Vec3f node;
    float best = -1.0f;
    std::size_t bestIndex = 0;

    FarthestOp(const float* p, float* d, const Vec3f& n) : points(p), minDist2(d), node(n) {}
    FarthestOp(FarthestOp& o, tbb::split) : points(o.points), minDist2(o.minDist2), node(o.node) {}

    void operator()(const tbb::blocked_range<std::size_t>& r)
    {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const float dx = points[3 * i] - node.x, dy = points[3 * i + 1] - node.y, dz = points[3 * i + 2] - node.z;
            const float d = std::min(minDist2[i], dx * dx + dy * dy + dz * dz);
            minDist2[i] = d;
            if (d > best) { best = d; bestIndex = i; } // strict: keeps the lowest index within a range
        }
    }
    void join(const FarthestOp& o)
    {
        if (o.best > best || (o.best == best && o.bestIndex < bestIndex)) { best = o.best; bestIndex = o.bestIndex; }
    }
};

} // namespace

DeformationGraph::DeformationGraph() = default;
DeformationGraph::~DeformationGraph() = default;
DeformationGraph::DeformationGraph(const DeformationGraph&) = default;
DeformationGraph::DeformationGraph(DeformationGraph&&) noexcept = default;
DeformationGraph& DeformationGraph::operator=(const DeformationGraph&) = default;
DeformationGraph& DeformationGraph::operator=(DeformationGraph&&) noexcept = default;

DeformationGraph DeformationGraph::build(const GaussianCloud& cloud, const GraphOptions& options, bool threaded)
{
    if (cloud.empty()) throw InputError("cannot build a deformation graph: the model has no Gaussians");
    if (options.nodes < 1) throw InputError(msg("graph node count must be >= 1 (got ", options.nodes, ")"));
    if (options.k < 1) throw InputError(msg("graph k must be >= 1 (got ", options.k, ")"));

    const std::size_t n = cloud.size();
    const float* pts = cloud.means.data();
    std::vector<float> minDist2(n, std::numeric_limits<float>::infinity());
    std::vector<Vec3d> nodes;
    nodes.reserve(std::size_t(options.nodes));
    std::size_t next = std::mt19937(options.seed)() % n;
    const std::size_t grain = 4096;
    while (nodes.size() < std::size_t(options.nodes)) {
        const Vec3f p = cloud.mean(next);
        nodes.emplace_back(p);
        FarthestOp op(pts, minDist2.data(), p);
        if (threaded)
            tbb::parallel_reduce(tbb::blocked_range<std::size_t>(0, n, grain), op);
        else
            op(tbb::blocked_range<std::size_t>(0, n));
        if (!(op.best > 0.0f)) break; // every centre coincides with a node already
        next = op.bestIndex;
    }
    return fromNodes(std::move(nodes), options.k);
}

DeformationGraph DeformationGraph::fromNodes(std::vector<Vec3d> nodes, int k)
{
    if (nodes.empty()) throw InputError("a deformation graph needs at least one node");
    if (k < 1) throw InputError(msg("graph k must be >= 1 (got ", k, ")"));
    DeformationGraph g;
    g.mNodes = std::move(nodes);
    g.mK = k;
    g.buildIndex();
    const std::size_t j = g.mNodes.size();
    const std::size_t query = std::min<std::size_t>(std::size_t(k) + 1, j);
    std::vector<std::int32_t> idx(query);
    std::vector<double> d2(query);
    g.mNeighbours.resize(j);
    for (std::size_t a = 0; a < j; ++a) {
        const double q[3] = {g.mNodes[a].x, g.mNodes[a].y, g.mNodes[a].z};
        const std::size_t found = g.mIndex->nearest(q, query, idx.data(), d2.data());
        for (std::size_t i = 0; i < found && g.mNeighbours[a].size() < std::size_t(k); ++i)
            if (std::size_t(idx[i]) != a) g.mNeighbours[a].push_back(idx[i]);
    }
    return g;
}

void DeformationGraph::buildIndex()
{
    auto index = std::make_shared<detail::NodeIndex>();
    index->cloud.xyz.reserve(3 * mNodes.size());
    for (const Vec3d& p : mNodes) index->cloud.xyz.insert(index->cloud.xyz.end(), {p.x, p.y, p.z});
    index->tree = std::make_unique<detail::NodeTree>(3, index->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    mIndex = std::move(index);
}

namespace {

/// Points looked up together: neighbours in a point list (a sample cell's samples) share their
/// nearest nodes, so each run's candidates are found once.
constexpr std::size_t kRun = 64;

/// |p - c|^2 in double for a float point p.
double squaredDistance(const float* p, const double* c)
{
    double d = 0;
    for (int a = 0; a < 3; ++a) d += (double(p[a]) - c[a]) * (double(p[a]) - c[a]);
    return d;
}

/// The nodes that may be among the `query` nearest of any point of a run: those within
/// d_query(c) + 2 r of the run's centre c, r the farthest point's distance from c (each point's
/// query nearest lie within d_query(c) + r of it, so within that of c). Ascending node order.
/// Empty when the list would not be much shorter than the tree's search (spread runs).
std::vector<std::int32_t> runCandidates(const detail::NodeIndex& index, const float* points, std::size_t r0,
                                        std::size_t r1, std::size_t query)
{
    const std::size_t j = index.cloud.kdtree_get_point_count();
    double lo[3], hi[3];
    for (int a = 0; a < 3; ++a) lo[a] = hi[a] = double(points[3 * r0 + std::size_t(a)]);
    for (std::size_t p = r0; p < r1; ++p)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], double(points[3 * p + std::size_t(a)]));
            hi[a] = std::max(hi[a], double(points[3 * p + std::size_t(a)]));
        }
    const double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    double r2 = 0;
    for (std::size_t p = r0; p < r1; ++p) r2 = std::max(r2, squaredDistance(points + 3 * p, c));
    std::vector<std::int32_t> idx(query);
    std::vector<double> d2(query);
    if (!(index.nearest(c, query, idx.data(), d2.data()) == query)) return {};
    // A relative allowance far above the rounding of these distances.
    const double reach = (std::sqrt(d2[query - 1]) + 2.0 * std::sqrt(r2)) * (1.0 + 1e-6) + 1e-12;
    std::vector<std::int32_t> out;
    for (std::size_t n = 0; n < j; ++n) {
        const double* node = index.cloud.xyz.data() + 3 * n;
        const double d = (node[0] - c[0]) * (node[0] - c[0]) + (node[1] - c[1]) * (node[1] - c[1]) +
                         (node[2] - c[2]) * (node[2] - c[2]);
        if (d <= reach * reach) out.push_back(std::int32_t(n));
        if (out.size() > std::max<std::size_t>(8 * query, j / 4)) return {};
    }
    return out;
}

/// Whether the first runs of the points (up to kProbeRuns) mostly fall back to the tree search.
bool spreadRuns(const detail::NodeIndex& index, const float* points, std::size_t count, std::size_t query)
{
    constexpr std::size_t kProbeRuns = 16;
    const std::size_t runs = std::min(kProbeRuns, count / kRun);
    std::size_t spread = 0;
    for (std::size_t r = 0; r < runs; ++r) spread += runCandidates(index, points, r * kRun, (r + 1) * kRun, query).empty();
    return 2 * spread > runs;
}

/// A run's candidate nodes, nearest the run's first point first (so each point's list fills with
/// near nodes and the rest are dropped at one comparison; insertNearest() gives the same list in
/// any order), coordinates by axis (for the distance loop).
struct RunNodes {
    std::vector<std::int32_t> id;
    std::vector<double> x, y, z;

    RunNodes(const std::vector<double>& xyz, std::vector<std::int32_t> candidates, const float* first);

private:
    /// x, y, z of the nodes of id, in its order.
    void place(const std::vector<double>& xyz)
    {
        x.clear();
        y.clear();
        z.clear();
        for (const std::int32_t n : id) {
            x.push_back(xyz[3 * std::size_t(n)]);
            y.push_back(xyz[3 * std::size_t(n) + 1]);
            z.push_back(xyz[3 * std::size_t(n) + 2]);
        }
    }
};

/// Squared distances from q to each node, the tree's arithmetic per lane ((dx^2 + dy^2) + dz^2 in
/// double): a loop without branches, vectorised.
SPLATWARP_SIMD_CLONES
void squaredDistances(const RunNodes& nodes, const double* q, double* d)
{
    const std::size_t n = nodes.id.size();
    const double *x = nodes.x.data(), *y = nodes.y.data(), *z = nodes.z.data();
    for (std::size_t c = 0; c < n; ++c) {
        const double dx = q[0] - x[c], dy = q[1] - y[c], dz = q[2] - z[c];
        d[c] = dx * dx + dy * dy + dz * dz;
    }
}

RunNodes::RunNodes(const std::vector<double>& xyz, std::vector<std::int32_t> candidates, const float* first)
    : id(std::move(candidates))
{
    place(xyz);
    const double q[3] = {first[0], first[1], first[2]};
    std::vector<double> d(id.size());
    squaredDistances(*this, q, d.data());
    // (a point that is not finite keeps the nodes' order: any order gives the same lists)
    if (!std::all_of(d.begin(), d.end(), [](double v) { return std::isfinite(v); })) return;
    std::vector<std::pair<double, std::int32_t>> byDistance;
    for (std::size_t c = 0; c < id.size(); ++c) byDistance.push_back({d[c], id[c]});
    std::sort(byDistance.begin(), byDistance.end());
    for (std::size_t c = 0; c < id.size(); ++c) id[c] = byDistance[c].second;
    place(xyz);
}

/// The `query` nearest of the candidate nodes to q, nearest first (ties: lower node first), with
/// the tree's distance arithmetic.
void nearestAmong(const RunNodes& nodes, const double* q, std::size_t query, std::int32_t* idx, double* d2,
                  std::vector<double>& scratch)
{
    scratch.resize(nodes.id.size());
    squaredDistances(nodes, q, scratch.data());
    std::size_t found = 0;
    for (std::size_t c = 0; c < nodes.id.size(); ++c) insertNearest(scratch[c], nodes.id[c], query, found, idx, d2);
}

} // namespace

SkinWeights DeformationGraph::skinWeights(const float* points, std::size_t count, bool threaded) const
{
    SkinWeights w;
    const std::size_t j = nodeCount();
    w.k = int(std::min<std::size_t>(std::size_t(mK), j));
    const std::size_t k = std::size_t(w.k);
    w.nodes.resize(count * k);
    w.weights.resize(count * k);
    const std::size_t query = std::min(k + 1, j);
    // Runs of points that share their candidate nodes: in the caller's order when its runs are
    // compact (a sample cell's samples), else in Morton order (a Gaussian's endpoints, random
    // points: guitar's curve split fell back to the tree for 78% of its runs). Fixed runs (not the
    // threads' ranges), so each point's search is the same for any thread count.
    const std::optional<MortonOrder> sorted =
        spreadRuns(*mIndex, points, count, query) ? std::make_optional<MortonOrder>(points, count, threaded) : std::nullopt;
    const auto at = [&](std::size_t s) { return sorted ? std::size_t(sorted->order[s]) : s; };
    parallelFor((count + kRun - 1) / kRun, 4, threaded, [&](std::size_t run) {
        const std::size_t r0 = run * kRun, r1 = std::min(count, r0 + kRun);
        std::vector<float> x(3 * (r1 - r0));
        for (std::size_t s = r0; s != r1; ++s) std::copy_n(points + 3 * at(s), 3, &x[3 * (s - r0)]);
        const RunNodes candidates(mIndex->cloud.xyz, runCandidates(*mIndex, x.data(), 0, r1 - r0, query), x.data());
        std::vector<std::int32_t> idx(query);
        std::vector<double> d2(query), wt(k), scratch;
        for (std::size_t s = r0; s != r1; ++s) {
            const float* xp = &x[3 * (s - r0)];
            const double q[3] = {xp[0], xp[1], xp[2]};
            if (candidates.id.empty())
                mIndex->nearest(q, query, idx.data(), d2.data());
            else
                nearestAmong(candidates, q, query, idx.data(), d2.data(), scratch);
            const std::size_t p = at(s);
            skinWeightsFromDistances(d2.data(), query, k, wt.data(), &w.weights[p * k]);
            for (std::size_t i = 0; i < k; ++i) w.nodes[p * k + i] = idx[i];
        }
    });
    return w;
}

} // namespace splatwarp
