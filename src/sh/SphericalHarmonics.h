#pragma once
/// @file SphericalHarmonics.h
/// @brief The 3DGS real SH basis (degree 0..3, PlenOctrees constants and sign/ordering) and the
///        rotation of SH coefficients by any rotation.
#include "core/GaussianCloud.h"
#include "core/HostDevice.h"
#include "core/SmallMath.h"

namespace splatwarp {

/// Band-0 constant: RGB = 0.5 + kShC0 * f_dc.
constexpr double kShC0 = 0.28209479177387814;
constexpr double kShC1 = 0.4886025119029199;

/// @brief Evaluate the (d+1)^2 basis functions at a unit direction (x, y, z) into out[K].
template <typename T>
SPLATWARP_HOST_DEVICE void evalShBasis(int degree, const Vec3<T>& d, T* out)
{
    out[0] = T(kShC0);
    if (degree < 1) return;
    const T x = d.x, y = d.y, z = d.z;
    out[1] = -T(kShC1) * y;
    out[2] = T(kShC1) * z;
    out[3] = -T(kShC1) * x;
    if (degree < 2) return;
    const T xx = x * x, yy = y * y, zz = z * z, xy = x * y, yz = y * z, xz = x * z;
    out[4] = T(1.0925484305920792) * xy;
    out[5] = T(-1.0925484305920792) * yz;
    out[6] = T(0.31539156525252005) * (2 * zz - xx - yy);
    out[7] = T(-1.0925484305920792) * xz;
    out[8] = T(0.5462742152960396) * (xx - yy);
    if (degree < 3) return;
    out[9] = T(-0.5900435899266435) * y * (3 * xx - yy);
    out[10] = T(2.890611442640554) * xy * z;
    out[11] = T(-0.4570457994644658) * y * (4 * zz - xx - yy);
    out[12] = T(0.3731763325901154) * z * (2 * zz - 3 * xx - 3 * yy);
    out[13] = T(-0.4570457994644658) * x * (4 * zz - xx - yy);
    out[14] = T(1.445305721320277) * z * (xx - yy);
    out[15] = T(-0.5900435899266435) * x * (xx - 3 * yy);
}

/// @brief Raw SH sum per channel (no +0.5, no clamp) for coefficients [K,3] at a direction
///        (need not be normalised; a zero direction gives the DC term only).
template <typename T, typename C>
SPLATWARP_HOST_DEVICE Vec3<T> evalShSum(int degree, const C* coeffs, Vec3<T> dir)
{
    const T n = std::sqrt(dot(dir, dir));
    dir = n > T(0) ? dir / n : Vec3<T>(0, 0, 0);
    T basis[16];
    evalShBasis(degree, dir, basis);
    Vec3<T> out(0, 0, 0);
    const int k = shCoeffCount(degree);
    for (int i = 0; i < k; ++i) {
        out.x += basis[i] * T(coeffs[3 * i]);
        out.y += basis[i] * T(coeffs[3 * i + 1]);
        out.z += basis[i] * T(coeffs[3 * i + 2]);
    }
    return out;
}

/// @brief 3DGS view-dependent colour: max(0, 0.5 + sum). dir points from the camera to the Gaussian.
template <typename T, typename C>
SPLATWARP_HOST_DEVICE Vec3<T> evalShColor(int degree, const C* coeffs, const Vec3<T>& dir)
{
    Vec3<T> s = evalShSum<T>(degree, coeffs, dir);
    for (int c = 0; c < 3; ++c) s[c] = s[c] + T(0.5) > T(0) ? s[c] + T(0.5) : T(0);
    return s;
}

/// @brief Band matrices that rotate SH coefficients by one rotation (built by buildShBands() in
///        sh/ShRotationMath.h): band l is (2l+1) x (2l+1) row-major; band 0 unused.
struct ShBands {
    double band[4][49];
};

/// @brief The per-band matrices that rotate SH coefficients by a rotation R: after apply(),
///        eval(coeffs', R d) == eval(coeffs, d) for every direction d. Band 0 is invariant.
/// @note  Built per rotation (once per Gaussian or sample), so construction is kept cheap:
///        fixed-size arrays, and only the bands up to the degree asked for.
class ShRotation {
public:
    /// @param r      a proper rotation matrix (orthonormal, det +1).
    /// @param degree highest band to build (apply() accepts degrees up to this).
    explicit ShRotation(const Mat3d& r, int degree = 3);
    /// @brief Rotate coefficients [K,3] (K = (degree+1)^2) in place; degree <= the built degree.
    void apply(int degree, float* coeffs) const;
    void apply(int degree, double* coeffs) const;
    /// @brief Band matrix entry D_l[i][j] (l = 1..built degree), mainly for tests.
    double band(int l, int i, int j) const { return mBands.band[l][i * (2 * l + 1) + j]; }

private:
    template <typename T>
    void applyImpl(int degree, T* coeffs) const;
    int mDegree;
    ShBands mBands; ///< built by buildShBands() (sh/ShRotationMath.h)
};

/// @brief Rotate the SH of every Gaussian of a cloud by the same rotation (rigid motions, tests).
void rotateCloudSh(GaussianCloud& cloud, const Mat3d& r);

} // namespace splatwarp
