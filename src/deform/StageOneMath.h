#pragma once
/// @file StageOneMath.h
/// @brief The Stage I per-Gaussian update on raw arrays in the GPU layout, host/device: the one
///        implementation behind applyStageOneCpu() (CPU) and the CUDA Stage I (kernels/StageOneCuda).
#include <cstddef>
#include <cstdint>

#include "core/HostDevice.h"
#include "core/Polar.h"
#include "core/SmallMath.h"
#include "deform/SkinningMath.h"
#include "sh/ShRotationMath.h"

namespace splatwarp {

/// Skinned points per Gaussian: the centre, then the endpoints +x,-x,+y,-y,+z,-z of its own axes.
constexpr std::size_t kStageOnePoints = 7;

/// @brief The numbers of StageOneOptions the update needs, plus the model extent (plain data).
struct StageOneParams {
    double endpointSigmas = 2.0;
    double flatEpsilon = 1e-3;
    double absoluteEpsilon = 1e-6;
    double minStretch = 1e-6;
    double extent = 1.0; ///< largest extent of the rest centres' bounding box
    bool affineShape = true; ///< StageOneShape::Affine (else Polar)
};

/// @brief Rest frame of a Gaussian: rotation (normalised quaternion), endpoint sigmas and centre.
struct StageOneRestFrame {
    Mat3d r0;
    Vec3d sigma;
    Vec3d centre;
};

SPLATWARP_HOST_DEVICE double stageOneMax(double a, double b) { return a < b ? b : a; } // std::max's choice

/// @brief Rest frame of Gaussian i from means [N,3], raw quaternions w,x,y,z [N,4], logScales [N,3].
SPLATWARP_HOST_DEVICE StageOneRestFrame stageOneRestFrame(const float* means, const float* rotations,
                                                          const float* logScales, std::size_t i,
                                                          const StageOneParams& p)
{
    const float* q = rotations + 4 * i;
    StageOneRestFrame f;
    f.r0 = quatToMatrix(Quatd{double(q[0]), double(q[1]), double(q[2]), double(q[3])});
    f.centre = Vec3d(means[3 * i], means[3 * i + 1], means[3 * i + 2]);
    const Vec3d s(std::exp(double(logScales[3 * i])), std::exp(double(logScales[3 * i + 1])),
                  std::exp(double(logScales[3 * i + 2])));
    // sigma = scale + eps: flat Gaussians keep a frame (relative eps), near-zero ones too (absolute).
    const double eps = stageOneMax(p.flatEpsilon * stageOneMax(stageOneMax(s.x, s.y), s.z), p.absoluteEpsilon * p.extent);
    f.sigma = Vec3d(s.x + eps, s.y + eps, s.z + eps);
    return f;
}

/// @brief Rest endpoint e (0..5: +x,-x,+y,-y,+z,-z of the Gaussian's own axes).
SPLATWARP_HOST_DEVICE Vec3d stageOneEndpoint(const StageOneRestFrame& f, int e, double sigmas)
{
    const int a = e / 2;
    const double sign = (e % 2 == 0) ? 1.0 : -1.0;
    const Vec3d axis(f.r0[0][a], f.r0[1][a], f.r0[2][a]);
    return f.centre + axis * (sign * sigmas * f.sigma[a]);
}

/// @brief Permute and flip the eigenvector columns of v (with their eigenvalues) to lie closest
///        to the identity's, det +1: the axes keep their rest order and sense where they can.
SPLATWARP_HOST_DEVICE void stageOneAlignToIdentity(Mat3d& v, Vec3d& lambda)
{
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    int best = 0;
    double bestScore = -1;
    for (int p = 0; p < 6; ++p) {
        double score = 0;
        for (int a = 0; a < 3; ++a) score += v[a][perms[p][a]] < 0 ? -v[a][perms[p][a]] : v[a][perms[p][a]];
        if (score > bestScore) {
            bestScore = score;
            best = p;
        }
    }
    Mat3d out;
    Vec3d l;
    int weakest = 0;
    for (int a = 0; a < 3; ++a) {
        const int k = perms[best][a];
        const double sign = v[a][k] < 0 ? -1.0 : 1.0;
        for (int r = 0; r < 3; ++r) out[r][a] = sign * v[r][k];
        l[a] = lambda[k];
        if (out[a][a] < out[weakest][weakest]) weakest = a;
    }
    if (out.determinant() < 0)
        for (int r = 0; r < 3; ++r) out[r][weakest] = -out[r][weakest];
    v = out;
    lambda = l;
}

/// @brief The affine shape: covariance M Sigma M^T of the rest covariance Sigma = R0 diag(s^2) R0^T
///        under the local map M = mr R0^T, as a rotation and log-scales. It is decomposed in the
///        polar frame rr0 (= R R0), where a rigid M leaves it diagonal: then the rotation is rr0 and
///        the scales the rest ones, as the polar shape gives, and the axes keep their order.
SPLATWARP_HOST_DEVICE void stageOneAffineShape(const Mat3d& mr, const Mat3d& rr0, const float* logScales, double minStretch,
                                               Quatd& q, float* outLogScales)
{
    const Mat3d b = rr0.transposed() * mr; // M R0 in the polar frame; M Sigma M^T = rr0 (b D b^T) rr0^T
    double variance[3];
    for (int a = 0; a < 3; ++a) variance[a] = std::exp(2.0 * double(logScales[a]));
    Mat3d c;
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) {
            double sum = 0;
            for (int a = 0; a < 3; ++a) sum += b[r][a] * b[k][a] * variance[a];
            c[r][k] = sum;
        }
    Vec3d lambda;
    Mat3d v;
    symmetricEigen3(c, lambda, v);
    // The thinnest axis of a flat Gaussian is below the rounding of the others' variances; take it
    // from det C = det(b)^2 s0^2 s1^2 s2^2 instead (the eigenvalues come descending).
    const double detB = b.determinant(), sumLog = double(logScales[0]) + double(logScales[1]) + double(logScales[2]);
    if (lambda[0] * lambda[1] > 0) lambda[2] = detB * detB * std::exp(2.0 * sumLog) / (lambda[0] * lambda[1]);
    stageOneAlignToIdentity(v, lambda);
    q = matrixToQuat(rr0 * v);
    // A flat axis can round to a tiny negative eigenvalue: floor it at the smallest rest scale times
    // minStretch, as the polar shape floors its stretch (keeps log-scales finite).
    double smallest = double(logScales[0]);
    for (int a = 1; a < 3; ++a) smallest = double(logScales[a]) < smallest ? double(logScales[a]) : smallest;
    const double floor = minStretch * std::exp(smallest);
    for (int a = 0; a < 3; ++a) outLogScales[a] = float(0.5 * std::log(stageOneMax(lambda[a], floor * floor)));
}

/// @brief Read-only inputs of the update, GPU layout (N Gaussians, K = (shDegree+1)^2).
struct StageOneInputs {
    const float* means = nullptr;         ///< [N,3] rest
    const float* rotations = nullptr;     ///< [N,4] rest, raw w,x,y,z
    const float* logScales = nullptr;     ///< [N,3] rest
    const std::int32_t* nodes = nullptr;  ///< [N*7,k] skin-weight nodes of the 7 points
    const float* weights = nullptr;       ///< [N*7,k] skin weights
    std::size_t k = 0;
    const NodeAffine* affines = nullptr;  ///< [J] node transforms
    const std::uint8_t* nodeMoving = nullptr; ///< [J] 0 for nodes at identity
    const ShRotationTables* shTables = nullptr;
    int shDegree = 0;
};

/// @brief Outputs, initialised by the caller to the rest values (static Gaussians are not written).
struct StageOneOutputs {
    float* means = nullptr;      ///< [N,3]
    float* rotations = nullptr;  ///< [N,4] unit quaternion, w >= 0
    float* logScales = nullptr;  ///< [N,3]
    float* sh = nullptr;         ///< [N,K,3], rotated in place
    std::uint8_t* moving = nullptr; ///< [N] 1 if any of its 7 points has weight on a moving node
};

/// @brief phi's second-order term along each own axis a of Gaussian i, h_a = 1/2 sigma_a^2
///        d^2 phi / dr_a^2 (world units; zero for an affine phi): the midpoint of the skinned
///        endpoints +-c sigma_a minus the skinned centre, over c^2. It is the offset at one sigma
///        along a that one Gaussian cannot follow.
struct StageOneCurvature {
    Vec3d h[3];
    SPLATWARP_HOST_DEVICE Vec3d sum() const { return h[0] + h[1] + h[2]; }
};

SPLATWARP_HOST_DEVICE StageOneCurvature stageOneCurvature(const StageOneInputs& in, const StageOneParams& p, std::size_t i)
{
    const StageOneRestFrame f = stageOneRestFrame(in.means, in.rotations, in.logScales, i, p);
    const std::size_t base = i * kStageOnePoints;
    const Vec3d centre = skinAffinePoint(in.affines, in.nodes, in.weights, in.k, base, f.centre);
    StageOneCurvature c;
    for (int a = 0; a < 3; ++a) {
        const Vec3d plus = skinAffinePoint(in.affines, in.nodes, in.weights, in.k, base + 1 + std::size_t(2 * a),
                                           stageOneEndpoint(f, 2 * a, p.endpointSigmas));
        const Vec3d minus = skinAffinePoint(in.affines, in.nodes, in.weights, in.k, base + 2 + std::size_t(2 * a),
                                            stageOneEndpoint(f, 2 * a + 1, p.endpointSigmas));
        c.h[a] = ((plus + minus) * 0.5 - centre) / (p.endpointSigmas * p.endpointSigmas);
    }
    return c;
}

/// @brief How far the skinning bends Gaussian i away from its affine Stage I shape: |h_a|
///        (stageOneCurvature) in the deformed Gaussian's own sigmas (rotation q, logScales: Stage
///        I's output for i), per own axis a.
SPLATWARP_HOST_DEVICE Vec3d stageOneBending(const StageOneCurvature& c, const float* q, const float* logScales)
{
    const Mat3d r = quatToMatrix(Quatd{double(q[0]), double(q[1]), double(q[2]), double(q[3])});
    Vec3d out;
    for (int a = 0; a < 3; ++a) {
        const Vec3d& h = c.h[a];
        double sum = 0;
        for (int b = 0; b < 3; ++b) {
            const double along = (r[0][b] * h[0] + r[1][b] * h[1] + r[2][b] * h[2]) * std::exp(-double(logScales[b]));
            sum += along * along;
        }
        out[a] = std::sqrt(sum);
    }
    return out;
}

/// @brief Whether Gaussian i moves: any of its 7 skinned points has weight on a moving node
///        (nodes / weights [N*7,k], nodeMoving [J]).
SPLATWARP_HOST_DEVICE bool stageOneMoves(const std::int32_t* nodes, const float* weights, std::size_t k,
                                         const std::uint8_t* nodeMoving, std::size_t i)
{
    for (std::size_t q = i * kStageOnePoints * k; q < (i + 1) * kStageOnePoints * k; ++q)
        if (weights[q] > 0.0f && nodeMoving[std::size_t(nodes[q])]) return true;
    return false;
}

/// @brief Update Gaussian i: skin its centre and endpoints, M = (P Q^T)(Q Q^T)^-1, polar M = R S,
///        then mean, shape (affine: covariance M Sigma M^T; polar: rotation R R0, log-scales + log
///        stretch) and SH rotated by R.
SPLATWARP_HOST_DEVICE void stageOneUpdate(const StageOneInputs& in, const StageOneParams& p, std::size_t i,
                                          const StageOneOutputs& out)
{
    const std::size_t k = in.k;
    const bool moving = stageOneMoves(in.nodes, in.weights, k, in.nodeMoving, i);
    out.moving[i] = moving ? 1 : 0;
    if (!moving) return;
    const StageOneRestFrame f = stageOneRestFrame(in.means, in.rotations, in.logScales, i, p);
    const std::size_t base = i * kStageOnePoints;
    const Vec3d centre = skinAffinePoint(in.affines, in.nodes, in.weights, k, base, f.centre);
    // With Q the symmetric endpoint offsets +-c sigma_a r_a, (P Q^T)(Q Q^T)^-1 reduces to
    // M r_a = (p_a+ - p_a-) / (2 c sigma_a): the same least-squares M without the 3x3 inverse.
    Mat3d mr; // columns M r_a
    for (int a = 0; a < 3; ++a) {
        const Vec3d plus = skinAffinePoint(in.affines, in.nodes, in.weights, k, base + 1 + std::size_t(2 * a),
                                           stageOneEndpoint(f, 2 * a, p.endpointSigmas));
        const Vec3d minus = skinAffinePoint(in.affines, in.nodes, in.weights, k, base + 2 + std::size_t(2 * a),
                                            stageOneEndpoint(f, 2 * a + 1, p.endpointSigmas));
        const Vec3d col = (plus - minus) / (2.0 * p.endpointSigmas * f.sigma[a]);
        for (int r = 0; r < 3; ++r) mr[r][a] = col[r];
    }
    // M = mr R0^T = R S gives mr = (R R0)(R0^T S R0): the polar factors of mr are the
    // deformed frame R R0 directly, and S's stretch along r_a is (R0^T S R0)_aa.
    Mat3d rr0; // R R0
    Vec3d stretch;
    if (polarRotationNewton(mr, rr0)) {
        for (int a = 0; a < 3; ++a)
            stretch[a] = rr0[0][a] * mr[0][a] + rr0[1][a] * mr[1][a] + rr0[2][a] * mr[2][a];
    } else {
        Mat3d r, s;
        polarDecomposition(mr * f.r0.transposed(), r, s);
        rr0 = r * f.r0;
        for (int a = 0; a < 3; ++a) {
            const Vec3d ra(f.r0[0][a], f.r0[1][a], f.r0[2][a]);
            stretch[a] = dot(ra, s * ra);
        }
    }
    Quatd q = matrixToQuat(rr0);
    if (p.affineShape) {
        stageOneAffineShape(mr, rr0, in.logScales + 3 * i, p.minStretch, q, out.logScales + 3 * i);
    } else {
        for (int a = 0; a < 3; ++a)
            out.logScales[3 * i + std::size_t(a)] =
                float(double(in.logScales[3 * i + std::size_t(a)]) + std::log(stageOneMax(stretch[a], p.minStretch)));
    }
    for (int a = 0; a < 3; ++a) out.means[3 * i + std::size_t(a)] = float(centre[a]);
    float* rot = out.rotations + 4 * i;
    rot[0] = float(q.w);
    rot[1] = float(q.x);
    rot[2] = float(q.y);
    rot[3] = float(q.z);
    if (in.shDegree > 0) {
        const std::size_t stride = std::size_t(3 * (in.shDegree + 1) * (in.shDegree + 1));
        rotateSh(*in.shTables, rr0 * f.r0.transposed(), in.shDegree, out.sh + i * stride);
    }
}

} // namespace splatwarp
