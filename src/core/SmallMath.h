#pragma once
/// @file SmallMath.h
/// @brief Tiny fixed-size vector/matrix/quaternion maths usable on host and device.
///        Eigen is used for host-only solvers; per-element maths shared with CUDA lives here.
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/HostDevice.h"

namespace splatwarp {

template <typename T>
struct Vec3 {
    T x = 0, y = 0, z = 0;
    Vec3() = default; // defaulted: host/device implicitly (an annotation here only draws nvcc warnings)
    SPLATWARP_HOST_DEVICE Vec3(T a, T b, T c) : x(a), y(b), z(c) {}
    template <typename U>
    SPLATWARP_HOST_DEVICE explicit Vec3(const Vec3<U>& o) : x(T(o.x)), y(T(o.y)), z(T(o.z)) {}
    SPLATWARP_HOST_DEVICE T& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
    SPLATWARP_HOST_DEVICE T operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    SPLATWARP_HOST_DEVICE Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    SPLATWARP_HOST_DEVICE Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    SPLATWARP_HOST_DEVICE Vec3 operator-() const { return {-x, -y, -z}; }
    SPLATWARP_HOST_DEVICE Vec3 operator*(T s) const { return {x * s, y * s, z * s}; }
    SPLATWARP_HOST_DEVICE Vec3 operator/(T s) const { return {x / s, y / s, z / s}; }
    SPLATWARP_HOST_DEVICE Vec3& operator+=(const Vec3& o) { x += o.x; y += o.y; z += o.z; return *this; }
    SPLATWARP_HOST_DEVICE Vec3& operator-=(const Vec3& o) { x -= o.x; y -= o.y; z -= o.z; return *this; }
    SPLATWARP_HOST_DEVICE Vec3& operator*=(T s) { x *= s; y *= s; z *= s; return *this; }
};
using Vec3f = Vec3<float>;
using Vec3d = Vec3<double>;

template <typename T>
SPLATWARP_HOST_DEVICE T dot(const Vec3<T>& a, const Vec3<T>& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <typename T>
SPLATWARP_HOST_DEVICE Vec3<T> cross(const Vec3<T>& a, const Vec3<T>& b)
{
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <typename T>
SPLATWARP_HOST_DEVICE T length(const Vec3<T>& a) { return std::sqrt(dot(a, a)); }
/// @brief a / |a| scaled by its largest component first, so that |a| cannot overflow or underflow
///        (a spec's rotation axis [1e200, 0, 0] became the zero vector: a collapse, not a turn);
///        the zero vector for a zero (or non-finite) a.
inline Vec3d unitVector(const Vec3d& a)
{
    const double big = std::max(std::abs(a.x), std::max(std::abs(a.y), std::abs(a.z)));
    if (!(big > 0 && big <= std::numeric_limits<double>::max())) return {0, 0, 0};
    const Vec3d b{a.x / big, a.y / big, a.z / big};
    const double len = length(b);
    return {b.x / len, b.y / len, b.z / len};
}

/// @brief Row-major 3x3 matrix: m[r][c].
template <typename T>
struct Mat3 {
    T m[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
    SPLATWARP_HOST_DEVICE static Mat3 identity()
    {
        Mat3 r;
        r.m[0][0] = r.m[1][1] = r.m[2][2] = T(1);
        return r;
    }
    template <typename U>
    SPLATWARP_HOST_DEVICE static Mat3 from(const Mat3<U>& o)
    {
        Mat3 r;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) r.m[i][j] = T(o.m[i][j]);
        return r;
    }
    /// @brief From 9 values in row-major order (a cell gradient, a stored filter).
    template <typename U>
    SPLATWARP_HOST_DEVICE static Mat3 fromRowMajor(const U* a)
    {
        Mat3 r;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) r.m[i][j] = T(a[3 * i + j]);
        return r;
    }
    SPLATWARP_HOST_DEVICE T* operator[](int r) { return m[r]; }
    SPLATWARP_HOST_DEVICE const T* operator[](int r) const { return m[r]; }
    SPLATWARP_HOST_DEVICE Vec3<T> operator*(const Vec3<T>& v) const
    {
        return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
    }
    SPLATWARP_HOST_DEVICE Mat3 operator*(const Mat3& o) const
    {
        Mat3 r;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) r.m[i][j] = m[i][0] * o.m[0][j] + m[i][1] * o.m[1][j] + m[i][2] * o.m[2][j];
        return r;
    }
    SPLATWARP_HOST_DEVICE Mat3 operator+(const Mat3& o) const
    {
        Mat3 r;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) r.m[i][j] = m[i][j] + o.m[i][j];
        return r;
    }
    SPLATWARP_HOST_DEVICE Mat3 operator*(T s) const
    {
        Mat3 r;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) r.m[i][j] = m[i][j] * s;
        return r;
    }
    SPLATWARP_HOST_DEVICE Mat3 transposed() const
    {
        Mat3 r;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) r.m[i][j] = m[j][i];
        return r;
    }
    SPLATWARP_HOST_DEVICE T determinant() const
    {
        return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
               m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    }
    /// @brief Inverse of a symmetric matrix (covariances); caller guarantees it is non-singular.
    SPLATWARP_HOST_DEVICE Mat3 inverse() const
    {
        Mat3 r;
        r.m[0][0] = m[1][1] * m[2][2] - m[1][2] * m[2][1];
        r.m[0][1] = m[0][2] * m[2][1] - m[0][1] * m[2][2];
        r.m[0][2] = m[0][1] * m[1][2] - m[0][2] * m[1][1];
        r.m[1][0] = m[1][2] * m[2][0] - m[1][0] * m[2][2];
        r.m[1][1] = m[0][0] * m[2][2] - m[0][2] * m[2][0];
        r.m[1][2] = m[0][2] * m[1][0] - m[0][0] * m[1][2];
        r.m[2][0] = m[1][0] * m[2][1] - m[1][1] * m[2][0];
        r.m[2][1] = m[0][1] * m[2][0] - m[0][0] * m[2][1];
        r.m[2][2] = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        const T inv = T(1) / determinant();
        return r * inv;
    }
};
using Mat3f = Mat3<float>;
using Mat3d = Mat3<double>;

/// @brief Quaternion (w, x, y, z) as stored by 3DGS.
template <typename T>
struct Quat {
    T w = 1, x = 0, y = 0, z = 0;
};
using Quatf = Quat<float>;
using Quatd = Quat<double>;

/// @brief Rotation matrix of a quaternion, normalised on use (3DGS stores raw quaternions).
template <typename T>
SPLATWARP_HOST_DEVICE Mat3<T> quatToMatrix(const Quat<T>& qIn)
{
    const T n = std::sqrt(qIn.w * qIn.w + qIn.x * qIn.x + qIn.y * qIn.y + qIn.z * qIn.z);
    const T inv = n > T(0) ? T(1) / n : T(0);
    const T w = n > T(0) ? qIn.w * inv : T(1), x = qIn.x * inv, y = qIn.y * inv, z = qIn.z * inv;
    Mat3<T> r;
    r.m[0][0] = 1 - 2 * (y * y + z * z); r.m[0][1] = 2 * (x * y - w * z);     r.m[0][2] = 2 * (x * z + w * y);
    r.m[1][0] = 2 * (x * y + w * z);     r.m[1][1] = 1 - 2 * (x * x + z * z); r.m[1][2] = 2 * (y * z - w * x);
    r.m[2][0] = 2 * (x * z - w * y);     r.m[2][1] = 2 * (y * z + w * x);     r.m[2][2] = 1 - 2 * (x * x + y * y);
    return r;
}

/// @brief Unit quaternion (w >= 0) of a proper rotation matrix (Shepperd's method, stable for all angles).
template <typename T>
SPLATWARP_HOST_DEVICE Quat<T> matrixToQuat(const Mat3<T>& r)
{
    Quat<T> q;
    const T tr = r.m[0][0] + r.m[1][1] + r.m[2][2];
    if (tr > 0) {
        const T s = std::sqrt(tr + T(1)) * 2;
        q.w = s / 4; q.x = (r.m[2][1] - r.m[1][2]) / s; q.y = (r.m[0][2] - r.m[2][0]) / s; q.z = (r.m[1][0] - r.m[0][1]) / s;
    } else if (r.m[0][0] > r.m[1][1] && r.m[0][0] > r.m[2][2]) {
        const T s = std::sqrt(T(1) + r.m[0][0] - r.m[1][1] - r.m[2][2]) * 2;
        q.w = (r.m[2][1] - r.m[1][2]) / s; q.x = s / 4; q.y = (r.m[0][1] + r.m[1][0]) / s; q.z = (r.m[0][2] + r.m[2][0]) / s;
    } else if (r.m[1][1] > r.m[2][2]) {
        const T s = std::sqrt(T(1) + r.m[1][1] - r.m[0][0] - r.m[2][2]) * 2;
        q.w = (r.m[0][2] - r.m[2][0]) / s; q.x = (r.m[0][1] + r.m[1][0]) / s; q.y = s / 4; q.z = (r.m[1][2] + r.m[2][1]) / s;
    } else {
        const T s = std::sqrt(T(1) + r.m[2][2] - r.m[0][0] - r.m[1][1]) * 2;
        q.w = (r.m[1][0] - r.m[0][1]) / s; q.x = (r.m[0][2] + r.m[2][0]) / s; q.y = (r.m[1][2] + r.m[2][1]) / s; q.z = s / 4;
    }
    if (q.w < 0) { q.w = -q.w; q.x = -q.x; q.y = -q.y; q.z = -q.z; }
    return q;
}

SPLATWARP_HOST_DEVICE float sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }
SPLATWARP_HOST_DEVICE double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

} // namespace splatwarp
