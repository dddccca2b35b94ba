#include "fit/MomentInit.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <queue>

#include "core/Error.h"

namespace splatwarp {

namespace {

struct Cluster {
    std::size_t begin = 0, end = 0; ///< range of the permutation
    double mass = 0;
    bool operator<(const Cluster& o) const { return mass < o.mass; } // max-heap on mass
};

double clusterMass(const VoxelSamples& v, const std::vector<std::uint32_t>& perm, std::size_t b, std::size_t e)
{
    double m = 0;
    for (std::size_t i = b; i < e; ++i) m += v.values[perm[i]];
    return m;
}

/// Split a cluster at its median along the axis of largest extent.
std::size_t splitCluster(const VoxelSamples& v, std::vector<std::uint32_t>& perm, const Cluster& c)
{
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    for (std::size_t i = c.begin; i < c.end; ++i)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], v.positions[3 * perm[i] + a]);
            hi[a] = std::max(hi[a], v.positions[3 * perm[i] + a]);
        }
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
    const std::size_t mid = c.begin + (c.end - c.begin) / 2;
    std::nth_element(perm.begin() + std::ptrdiff_t(c.begin), perm.begin() + std::ptrdiff_t(mid),
                     perm.begin() + std::ptrdiff_t(c.end), [&](std::uint32_t p, std::uint32_t q) {
                         const float x = v.positions[3 * p + axis], y = v.positions[3 * q + axis];
                         return x < y || (x == y && p < q);
                     });
    return mid;
}

/// Append the Gaussian of one cluster's moments (nothing for a massless cluster).
void appendMomentGaussian(const VoxelSamples& v, const std::vector<std::uint32_t>& perm, const Cluster& c,
                          const MomentInitOptions& o, GaussianCloud& out)
{
    if (!(c.mass > 0)) return;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t i = c.begin; i < c.end; ++i)
        mean += v.values[perm[i]] * Eigen::Vector3d(v.positions[3 * perm[i]], v.positions[3 * perm[i] + 1], v.positions[3 * perm[i] + 2]);
    mean /= c.mass;
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    const int stride = 3 * shCoeffCount(v.shDegree);
    std::vector<double> sh(std::size_t(stride), 0.0);
    for (std::size_t i = c.begin; i < c.end; ++i) {
        const std::uint32_t p = perm[i];
        const Eigen::Vector3d d = Eigen::Vector3d(v.positions[3 * p], v.positions[3 * p + 1], v.positions[3 * p + 2]) - mean;
        cov += (v.values[p] / c.mass) * d * d.transpose();
        for (int s = 0; s < stride; ++s) sh[std::size_t(s)] += v.features[std::size_t(p) * std::size_t(stride) + std::size_t(s)];
    }
    cov *= o.spread * o.spread;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    // Values are point samples at voxel centres, so the moments need no box term; a floor of one
    // voxel box's variance keeps single-voxel and flat clusters from degenerating.
    Eigen::Vector3d var = eig.eigenvalues().cwiseMax(v.voxelSize * v.voxelSize / 12.0);
    Eigen::Matrix3d axes = eig.eigenvectors();
    if (axes.determinant() < 0) axes.col(2) *= -1.0;
    const double volume = c.mass * v.voxelSize * v.voxelSize * v.voxelSize;
    const double kNorm = std::pow(2.0 * M_PI, 1.5);
    double alpha = volume / (kNorm * std::sqrt(var.prod()));
    if (alpha > o.maxAlpha) { // widen isotropically until the mass fits under maxAlpha
        var *= std::pow(alpha / o.maxAlpha, 2.0 / 3.0);
        alpha = o.maxAlpha;
    }
    // The filter keeps alpha and widens: alpha is the filtered moments', the Gaussian is narrower.
    var = (var.array() - o.filterVariance).cwiseMax(v.voxelSize * v.voxelSize / 12.0);
    Mat3d r;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) r.m[a][b] = axes(a, b);
    const Quatd q = matrixToQuat(r);
    alpha = std::max(alpha, 1e-6);
    for (int a = 0; a < 3; ++a) out.means.push_back(float(mean[a]));
    for (double x : {q.w, q.x, q.y, q.z}) out.rotations.push_back(float(x));
    for (int a = 0; a < 3; ++a) out.logScales.push_back(float(0.5 * std::log(var[a])));
    out.opacities.push_back(float(std::log(alpha / (1.0 - alpha))));
    for (int s = 0; s < stride; ++s) out.sh.push_back(float(sh[std::size_t(s)] / c.mass));
}

} // namespace

std::size_t defaultGaussianBudget(std::size_t voxels) { return std::max<std::size_t>(1, voxels / 8); }

GaussianCloud initFromMoments(const VoxelSamples& v, const MomentInitOptions& o)
{
    const std::size_t count = v.size();
    const std::size_t stride = std::size_t(3 * shCoeffCount(v.shDegree));
    if (v.positions.size() != 3 * count || v.features.size() != stride * count)
        throw InputError("moment initialisation: voxel arrays disagree in size");
    if (!(v.voxelSize > 0)) throw InputError("moment initialisation: voxel size must be positive");
    const std::size_t budget = o.gaussians > 0 ? o.gaussians : defaultGaussianBudget(count);
    std::vector<std::uint32_t> perm(count);
    std::iota(perm.begin(), perm.end(), 0u);
    std::priority_queue<Cluster> heap;
    std::vector<Cluster> done; // clusters that cannot split (single voxel)
    // Only clusters with mass become Gaussians, so only they count against the budget.
    std::size_t clusters = 1;
    heap.push({0, count, clusterMass(v, perm, 0, count)});
    while (!heap.empty() && clusters < budget) {
        const Cluster c = heap.top();
        heap.pop();
        if (!(c.mass > 0)) break; // the heap is ordered by mass: nothing left to split
        if (c.end - c.begin < 2) {
            done.push_back(c);
            continue;
        }
        const std::size_t mid = splitCluster(v, perm, c);
        const Cluster a{c.begin, mid, clusterMass(v, perm, c.begin, mid)}, b{mid, c.end, clusterMass(v, perm, mid, c.end)};
        clusters += std::size_t(a.mass > 0) + std::size_t(b.mass > 0) - 1;
        heap.push(a);
        heap.push(b);
    }
    for (; !heap.empty(); heap.pop()) done.push_back(heap.top());
    std::sort(done.begin(), done.end(), [](const Cluster& a, const Cluster& b) { return a.begin < b.begin; });
    GaussianCloud out;
    out.shDegree = v.shDegree;
    for (const Cluster& c : done) appendMomentGaussian(v, perm, c, o, out);
    return out;
}

} // namespace splatwarp
