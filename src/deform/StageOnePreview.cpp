/// @file StageOnePreview.cpp
/// @brief applyStageOnePreview(): Stage I for the editor's drag, in float. The map is
///        stageOneUpdate()'s (skinned endpoints, M's columns, its polar frame, the affine or polar
///        shape). What makes it cheaper: float throughout, the rest endpoints read from the rig
///        instead of rebuilt, no SH, no axis order (a renderer needs the covariance only), and the
///        affine shape's eigen-decomposition run on eight Gaussians at once (AVX2 lanes) for a
///        fixed number of sweeps. Where float's polar iteration fails the exact update runs.
#include <algorithm>
#include <cmath>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "core/Simd.h"
#include "deform/StageOne.h"
#include "deform/StageOneMath.h"

namespace splatwarp {

namespace {

constexpr std::size_t kPoints = kStageOnePoints;

/// Four floats in one register (GCC's vector extension: SSE on x86-64, NEON on aarch64).
typedef float Float4 __attribute__((vector_size(16)));

/// A node's affine map as four columns of four floats (A's three, then b; the fourth row 0), so
/// the skinning sum is four 4-lane multiply-adds per node.
struct AffineF {
    Float4 c[4];
};

std::vector<AffineF> floatAffines(const std::vector<NodeAffine>& affines)
{
    std::vector<AffineF> out(affines.size());
    for (std::size_t j = 0; j < affines.size(); ++j)
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) out[j].c[c][r] = float(affines[j].a[r][c]);
            out[j].c[3][r] = float(affines[j].b[r]);
            for (int c = 0; c < 4; ++c) out[j].c[c][3] = 0.0f;
        }
    return out;
}

/// skinAffinePoint() in float, of a rest point v of the rig.
inline Vec3f skinPoint(const AffineF* affines, const std::int32_t* nodes, const float* weights, std::size_t k, std::size_t q,
                       const float* v)
{
    Float4 acc = {0.0f, 0.0f, 0.0f, 0.0f};
    float sum = 0.0f;
    for (std::size_t e = q * k; e < (q + 1) * k; ++e) {
        const float w = weights[e];
        const AffineF& n = affines[std::size_t(nodes[e])];
        acc += n.c[0] * (w * v[0]) + n.c[1] * (w * v[1]) + n.c[2] * (w * v[2]) + n.c[3] * w;
        sum += w;
    }
    const float inv = 1.0f / sum;
    return {acc[0] * inv, acc[1] * inv, acc[2] * inv};
}

constexpr int kLanes = kSimdLanes;
/// Cyclic Jacobi sweeps of the batched eigen-decomposition. In the polar frame the shape is near
/// diagonal and each sweep squares what is left: 3 reach float's rounding on 1:100 needles under
/// every sample spec, 2 leave up to 4e-3 of the covariance (tests/deform/StageOnePreviewTest.cpp).
constexpr int kSweeps = 4;

/// Eight Gaussians' covariances in their polar frames (lanes), and the eigenvectors found.
struct ShapeBatch {
    float a[6][kLanes] = {}; ///< c00, c11, c22, c01, c02, c12
    float v[3][3][kLanes] = {};
};

/// One Jacobi rotation in the (p, q) plane of every lane, zeroing a_pq (Numerical Recipes' form;
/// the same rotation as symmetricEigen3()); r is the third axis. Straight-line per lane, so it
/// vectorises.
[[gnu::always_inline]] inline void jacobiRotate(ShapeBatch& s, int p, int q, int pq, int rp, int rq)
{
    for (int l = 0; l < kLanes; ++l) {
        const float apq = s.a[pq][l], app = s.a[p][l], aqq = s.a[q][l];
        const float theta = (aqq - app) / (2.0f * apq);
        const float mag = 1.0f / (std::fabs(theta) + std::sqrt(theta * theta + 1.0f));
        const float t = apq != 0.0f ? (theta < 0.0f ? -mag : mag) : 0.0f; // also drops theta = NaN
        const float c = 1.0f / std::sqrt(t * t + 1.0f), sn = t * c;
        s.a[p][l] = app - t * apq;
        s.a[q][l] = aqq + t * apq;
        s.a[pq][l] = 0.0f;
        const float arp = s.a[rp][l], arq = s.a[rq][l];
        s.a[rp][l] = c * arp - sn * arq;
        s.a[rq][l] = sn * arp + c * arq;
        for (int k = 0; k < 3; ++k) {
            const float vkp = s.v[k][p][l], vkq = s.v[k][q][l];
            s.v[k][p][l] = c * vkp - sn * vkq;
            s.v[k][q][l] = sn * vkp + c * vkq;
        }
    }
}

SPLATWARP_SIMD_CLONES void eigenBatch(ShapeBatch& s)
{
    for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j)
            for (int l = 0; l < kLanes; ++l) s.v[k][j][l] = k == j ? 1.0f : 0.0f;
    for (int sweep = 0; sweep < kSweeps; ++sweep) {
        jacobiRotate(s, 0, 1, 3, 4, 5);
        jacobiRotate(s, 0, 2, 4, 3, 5);
        jacobiRotate(s, 1, 2, 5, 3, 4);
    }
}

/// What one lane needs between its skinning and its output.
struct LaneState {
    std::size_t i = 0; ///< the Gaussian
    Mat3f rr0;         ///< polar frame R R0
    Mat3f mr;          ///< M's columns M r_a
    float detB = 0;    ///< det of M in the polar frame (the thinnest axis of a flat Gaussian)
};

/// Skin Gaussian i's centre (written) and endpoints into M's columns and its polar frame;
/// false where the polar iteration fails in float.
bool skinOne(const StageOneRig& rig, const AffineF* affines, std::size_t i, float* mean, LaneState& lane)
{
    const std::size_t k = std::size_t(rig.weights.k);
    const std::int32_t* nodes = rig.weights.nodes.data();
    const float* weights = rig.weights.weights.data();
    const float* points = rig.points.data() + i * kPoints * 3;
    const Vec3f centre = skinPoint(affines, nodes, weights, k, i * kPoints, points);
    for (int a = 0; a < 3; ++a) { // M r_a = (p_a+ - p_a-) / |rest p_a+ - rest p_a-|
        const float* plusRest = points + 3 * (1 + 2 * a);
        const float* minusRest = points + 3 * (2 + 2 * a);
        const Vec3f span(plusRest[0] - minusRest[0], plusRest[1] - minusRest[1], plusRest[2] - minusRest[2]);
        const Vec3f plus = skinPoint(affines, nodes, weights, k, i * kPoints + 1 + std::size_t(2 * a), plusRest);
        const Vec3f minus = skinPoint(affines, nodes, weights, k, i * kPoints + 2 + std::size_t(2 * a), minusRest);
        const Vec3f col = (plus - minus) / length(span);
        for (int r = 0; r < 3; ++r) lane.mr.m[r][a] = col[r];
    }
    if (!polarRotationNewton(lane.mr, lane.rr0)) return false;
    lane.i = i;
    for (int a = 0; a < 3; ++a) mean[a] = centre[a];
    return true;
}

void putQuat(const Mat3f& r, float* q)
{
    const Quatf quat = matrixToQuat(r);
    q[0] = quat.w;
    q[1] = quat.x;
    q[2] = quat.y;
    q[3] = quat.z;
}

/// The affine shape's covariance b D b^T in the polar frame (b = rr0^T mr), into lane l.
void shapeInto(LaneState& lane, const float* logScales, ShapeBatch& s, int l)
{
    const Mat3f b = lane.rr0.transposed() * lane.mr;
    lane.detB = std::fabs(b.determinant());
    float variance[3];
    for (int a = 0; a < 3; ++a) variance[a] = std::exp(2.0f * logScales[a]);
    const auto entry = [&](int r, int k) {
        return b.m[r][0] * b.m[k][0] * variance[0] + b.m[r][1] * b.m[k][1] * variance[1] + b.m[r][2] * b.m[k][2] * variance[2];
    };
    s.a[0][l] = entry(0, 0);
    s.a[1][l] = entry(1, 1);
    s.a[2][l] = entry(2, 2);
    s.a[3][l] = entry(0, 1);
    s.a[4][l] = entry(0, 2);
    s.a[5][l] = entry(1, 2);
}

/// Lane l's rotation rr0 V and log-scales, in logs so nothing underflows: the thinnest axis of a
/// flat Gaussian from det C = det(b)^2 s0^2 s1^2 s2^2, as the exact shape takes it, and each
/// floored at minStretch times the smallest rest scale (as the polar shape floors its stretch).
void shapeOut(const LaneState& lane, const ShapeBatch& s, int l, const float* restLogScales, float logMinStretch,
              float* q, float* logScales)
{
    Mat3f v;
    for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j) v.m[k][j] = s.v[k][j][l];
    putQuat(lane.rr0 * v, q);
    const float lambda[3] = {s.a[0][l], s.a[1][l], s.a[2][l]};
    const int thin = lambda[0] < lambda[1] ? (lambda[0] < lambda[2] ? 0 : 2) : (lambda[1] < lambda[2] ? 1 : 2);
    float sumOthers = 0.0f;
    for (int a = 0; a < 3; ++a) {
        logScales[a] = 0.5f * std::log(std::max(lambda[a], 0.0f));
        if (a != thin) sumOthers += logScales[a];
    }
    if (std::isfinite(sumOthers))
        logScales[thin] = std::log(lane.detB) + restLogScales[0] + restLogScales[1] + restLogScales[2] - sumOthers;
    const float floor = logMinStretch + std::min({restLogScales[0], restLogScales[1], restLogScales[2]});
    for (int a = 0; a < 3; ++a) logScales[a] = std::max(logScales[a], floor);
}

/// The polar shape: rotation rr0, log-scales plus the log stretch along each rest axis.
void polarOut(const LaneState& lane, const float* restLogScales, float minStretch, float* q, float* logScales)
{
    putQuat(lane.rr0, q);
    for (int a = 0; a < 3; ++a) {
        const float stretch = lane.rr0.m[0][a] * lane.mr.m[0][a] + lane.rr0.m[1][a] * lane.mr.m[1][a] +
                              lane.rr0.m[2][a] * lane.mr.m[2][a];
        logScales[a] = restLogScales[a] + std::log(std::max(stretch, minStretch));
    }
}

/// Indices of the Gaussians with weight on a moving node.
std::vector<std::uint32_t> movingGaussians(const StageOneRig& rig, const std::vector<std::uint8_t>& nodeMoving)
{
    const std::size_t n = rig.size(), k = std::size_t(rig.weights.k);
    std::vector<std::uint32_t> out;
    out.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
        if (stageOneMoves(rig.weights.nodes.data(), rig.weights.weights.data(), k, nodeMoving.data(), i))
            out.push_back(std::uint32_t(i));
    return out;
}

} // namespace

std::size_t applyStageOnePreview(const GaussianCloud& rest, const StageOneRig& rig, const DeformationGraph& graph,
                                 const NodeTransforms& transforms, const std::vector<std::uint8_t>& nodeMoving,
                                 const StageOneOptions& o, GaussianCloud& preview)
{
    if (preview.size() != rest.size() || preview.shDegree != 0)
        throw UsageError(msg("Stage I preview: the preview cloud holds ", preview.size(), " Gaussians of SH degree ",
                             preview.shDegree, " for a model of ", rest.size(), " (make it with withShDegree(rest, 0))"));
    checkStageOneInputs(rest, rig, graph, transforms, nodeMoving);
    // Gaussians that moved in the last preview and not in this one must read as rest again.
    std::copy(rest.means.begin(), rest.means.end(), preview.means.begin());
    std::copy(rest.rotations.begin(), rest.rotations.end(), preview.rotations.begin());
    std::copy(rest.logScales.begin(), rest.logScales.end(), preview.logScales.begin());
    const std::vector<NodeAffine> affines = nodeAffines(graph, transforms);
    const std::vector<AffineF> affinesF = floatAffines(affines);
    const StageOneParams params = stageOneParams(o, rig.extent);
    // The exact update, for the Gaussians float cannot take.
    StageOneInputs in = stageOneInputs(rest, rig, affines.data());
    in.nodeMoving = nodeMoving.data();
    std::vector<std::uint8_t> unused(rest.size());
    StageOneOutputs out;
    out.means = preview.means.data();
    out.rotations = preview.rotations.data();
    out.logScales = preview.logScales.data();
    out.moving = unused.data();
    const std::vector<std::uint32_t> moving = movingGaussians(rig, nodeMoving);
    const float minStretch = float(params.minStretch), logMinStretch = std::log(minStretch);
    const std::size_t batches = (moving.size() + kLanes - 1) / kLanes;
    parallelFor(batches, 8, o.threaded, [&](std::size_t batch) {
        ShapeBatch shapes;
        LaneState lanes[kLanes];
        int used = 0;
        for (std::size_t m = batch * kLanes; m < std::min(moving.size(), (batch + 1) * kLanes); ++m) {
            const std::size_t i = moving[m];
            if (!skinOne(rig, affinesF.data(), i, preview.means.data() + 3 * i, lanes[used])) {
                stageOneUpdate(in, params, i, out);
                continue;
            }
            if (params.affineShape) shapeInto(lanes[used], rest.logScales.data() + 3 * i, shapes, used);
            ++used;
        }
        if (params.affineShape) eigenBatch(shapes);
        for (int l = 0; l < used; ++l) {
            const std::size_t i = lanes[l].i;
            float* q = preview.rotations.data() + 4 * i;
            float* logScales = preview.logScales.data() + 3 * i;
            const float* restLogScales = rest.logScales.data() + 3 * i;
            if (params.affineShape) shapeOut(lanes[l], shapes, l, restLogScales, logMinStretch, q, logScales);
            else polarOut(lanes[l], restLogScales, minStretch, q, logScales);
        }
    });
    return moving.size();
}

} // namespace splatwarp
