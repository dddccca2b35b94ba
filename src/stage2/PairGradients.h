#pragma once
/// @file PairGradients.h
/// @brief Stage II forward/backward maths per sample, per (sample, Gaussian) pair and per
///        Gaussian, templated on the scalar so the tests run it in double against finite
///        differences. Host/device: the CUDA kernels use the same functions.
///
/// Chain (one pair, w = alpha G, d = x - mu, A = Sigma'^-1, q = d^T A d, G = exp(-q/2)):
///   dE/dw     = sum_c dE/dF_c H_c + dE/dO
///   dE/dH_c  += w dE/dF_c
///   dE/dmu   += dE/dw * w * A d
///   dE/dSigma' += dE/dw * w/2 * (A d)(A d)^T      (through A = Sigma'^-1)
///   dE/dalpha += dE/dw * w / alpha
/// then per Gaussian Sigma' = R V R^T + filter (V = diag s^2) gives the rotation and scale terms.
#include "core/HostDevice.h"
#include "core/SmallMath.h"
#include "field/PreparedGaussian.h"

namespace splatwarp {

/// @brief The raw (optimised) parameters of one Gaussian, SH excluded.
template <typename T>
struct GaussianParams {
    Vec3<T> mean;
    Quat<T> rotation; ///< raw quaternion (normalised on use)
    Vec3<T> logScale;
    T logit = 0;
};

/// @brief Per-Gaussian accumulators of the pair backward.
template <typename T>
struct GaussianAccum {
    Vec3<T> mean;   ///< dE/dmu
    Mat3<T> sigma;  ///< dE/dSigma' (symmetric)
    T alpha = 0;    ///< dE/dalpha
};

/// @brief Gradients with respect to the raw parameters.
template <typename T>
struct GaussianParamGrad {
    Vec3<T> mean;
    Quat<T> rotation = Quat<T>{0, 0, 0, 0};
    Vec3<T> logScale;
    T logit = 0;
};

/// @brief Adaptive low-pass filter lambda * spacing^2 * F F^T of a cell gradient F ([9] row-major).
template <typename T>
SPLATWARP_HOST_DEVICE Mat3<T> lowPassFilter(const float* f, T lambda, T spacing)
{
    Mat3<T> out;
    const T c = lambda * spacing * spacing;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
            T s = 0;
            for (int k = 0; k < 3; ++k) s += T(f[3 * a + k]) * T(f[3 * b + k]);
            out.m[a][b] = c * s;
        }
    return out;
}

/// @brief The prepared form of a Gaussian (PreparedGaussian) from its raw parameters and filter.
template <typename T>
SPLATWARP_HOST_DEVICE BasicPreparedGaussian<T> prepareParams(const GaussianParams<T>& p, const Mat3<T>& filter, T cutoff)
{
    const Vec3<T> s(std::exp(p.logScale.x), std::exp(p.logScale.y), std::exp(p.logScale.z));
    return prepareGaussian(p.mean, filteredCovariance(p.rotation, s, filter), sigmoid(p.logit), cutoff);
}

/// @brief L1 loss of one sample and its gradient.
/// @param f, fStar  [stride] current and target F; o, oStar: O
/// @param gF        [stride] out: dE/dF;  gO out: dE/dO
/// @param terms     out: [0] sum |F* - F|_1, [1] lambda1 |O* - O|, [2] lambda2 |O* - O| where O* = 0
/// @return the sample's energy terms[0] + terms[1] + terms[2]
template <typename T, typename S>
SPLATWARP_HOST_DEVICE T sampleLoss(const T* f, const S* fStar, T o, S oStar, int stride, T lambda1, T lambda2,
                                   T* gF, T& gO, T* terms)
{
    auto sign = [](T v) { return v > T(0) ? T(1) : (v < T(0) ? T(-1) : T(0)); };
    T e = 0;
    for (int c = 0; c < stride; ++c) {
        const T r = f[c] - T(fStar[c]);
        e += std::fabs(r);
        gF[c] = sign(r);
    }
    const T ro = o - T(oStar);
    const T weight = lambda1 + (oStar == S(0) ? lambda2 : T(0));
    terms[0] = e;
    terms[1] = lambda1 * std::fabs(ro);
    terms[2] = oStar == S(0) ? lambda2 * std::fabs(ro) : T(0);
    gO = weight * sign(ro);
    return terms[0] + terms[1] + terms[2];
}

/// @brief Backward of one counted pair: w = alpha G, ad = A d (from weight()), gw = dE/dw.
template <typename T>
SPLATWARP_HOST_DEVICE void pairBackward(T gw, T w, T alpha, const Vec3<T>& ad, GaussianAccum<T>& acc)
{
    const T gq = gw * w; // dE/dq = -gw w / 2; the factors below absorb the -2 and 1/2
    acc.mean += ad * gq;
    const T h = gq * T(0.5);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) acc.sigma.m[a][b] += h * ad[a] * ad[b];
    acc.alpha += gw * w / alpha;
}

/// @brief dE/dq_hat of the rotation matrix of a unit quaternion, given dE/dR.
template <typename T>
SPLATWARP_HOST_DEVICE Quat<T> quatMatrixBackward(const Quat<T>& q, const Mat3<T>& g)
{
    const T w = q.w, x = q.x, y = q.y, z = q.z;
    const Mat3<T>& G = g;
    Quat<T> o{0, 0, 0, 0};
    // Derivatives of each R entry (see quatToMatrix) with respect to w, x, y, z.
    o.w = 2 * (-z * G.m[0][1] + y * G.m[0][2] + z * G.m[1][0] - x * G.m[1][2] - y * G.m[2][0] + x * G.m[2][1]);
    o.x = 2 * (y * G.m[0][1] + z * G.m[0][2] + y * G.m[1][0] - 2 * x * G.m[1][1] - w * G.m[1][2] + z * G.m[2][0] +
               w * G.m[2][1] - 2 * x * G.m[2][2]);
    o.y = 2 * (-2 * y * G.m[0][0] + x * G.m[0][1] + w * G.m[0][2] + x * G.m[1][0] + z * G.m[1][2] - w * G.m[2][0] +
               z * G.m[2][1] - 2 * y * G.m[2][2]);
    o.z = 2 * (-2 * z * G.m[0][0] - w * G.m[0][1] + x * G.m[0][2] + w * G.m[1][0] - 2 * z * G.m[1][1] + y * G.m[1][2] +
               x * G.m[2][0] + y * G.m[2][1]);
    return o;
}

/// @brief From the accumulated dE/dmu, dE/dSigma', dE/dalpha to the raw parameters.
/// @note  The variance clamp (clampedVariances) is treated as constant where active.
template <typename T>
SPLATWARP_HOST_DEVICE GaussianParamGrad<T> paramBackward(const GaussianParams<T>& p, const GaussianAccum<T>& acc)
{
    GaussianParamGrad<T> out;
    out.mean = acc.mean;
    const T alpha = sigmoid(p.logit);
    out.logit = acc.alpha * alpha * (T(1) - alpha);

    const Vec3<T> s(std::exp(p.logScale.x), std::exp(p.logScale.y), std::exp(p.logScale.z));
    const Vec3<T> v = clampedVariances(s);
    const Mat3<T> r = quatToMatrix(p.rotation);
    // Symmetrise: only the symmetric part of dE/dSigma' is meaningful.
    Mat3<T> gs;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) gs.m[a][b] = T(0.5) * (acc.sigma.m[a][b] + acc.sigma.m[b][a]);
    // Sigma = R V R^T: dE/dV_kk = (R^T G R)_kk, dE/dR = 2 G R V.
    const Mat3<T> gr = gs * r;
    for (int k = 0; k < 3; ++k) {
        T dv = 0;
        for (int a = 0; a < 3; ++a) dv += r.m[a][k] * gr.m[a][k];
        out.logScale[k] = v[k] == s[k] * s[k] ? dv * T(2) * s[k] * s[k] : T(0);
    }
    Mat3<T> gR;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) gR.m[a][b] = T(2) * gr.m[a][b] * v[b];
    const Quat<T>& q = p.rotation;
    const T n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
    const Quat<T> qh{q.w / n, q.x / n, q.y / n, q.z / n};
    const Quat<T> gh = quatMatrixBackward(qh, gR);
    // Through the normalisation q_hat = q / |q|: (I - q_hat q_hat^T) g / |q|.
    const T proj = qh.w * gh.w + qh.x * gh.x + qh.y * gh.y + qh.z * gh.z;
    out.rotation = Quat<T>{(gh.w - qh.w * proj) / n, (gh.x - qh.x * proj) / n, (gh.y - qh.y * proj) / n,
                           (gh.z - qh.z * proj) / n};
    return out;
}

} // namespace splatwarp
