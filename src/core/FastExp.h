#pragma once
/// @file FastExp.h
/// @brief exp(x) for float in plain, branch-free arithmetic (Cody-Waite range reduction and the
///        Cephes degree-6 polynomial), written once for scalars and SIMD vectors (FastExpOps),
///        so the Stage II block loops vectorise it and the CUDA kernels (compiled with
///        -fmad=false) compute the same bits as the CPU. Relative error below 1.2e-7 on
///        [-87, 88] (tests/core/FastExpTest.cpp measures it); inputs are clamped to that range
///        (NaN to -87).
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/HostDevice.h"

namespace splatwarp {

/// @brief What fastExpOf() needs of a lane type: a constant in every lane, a per-lane select
///        on a comparison, and 2^n from lanes holding integers n. Specialised for float here
///        and for SIMD vectors where they are used (stage2/BlockLoops.cpp).
template <typename T>
struct FastExpOps;

template <>
struct FastExpOps<float> {
    SPLATWARP_HOST_DEVICE static float splat(float v) { return v; }
    SPLATWARP_HOST_DEVICE static float select(bool m, float a, float b) { return m ? a : b; }
    SPLATWARP_HOST_DEVICE static float pow2(float n)
    {
        const std::int32_t bits = (std::int32_t(n) + 127) << 23;
#if defined(__CUDA_ARCH__)
        return __int_as_float(bits);
#else
        float f;
        std::memcpy(&f, &bits, sizeof f);
        return f;
#endif
    }
};

/// @brief exp(x) on every lane, x clamped to [-87, 88] (the result stays a normal float).
template <typename T>
SPLATWARP_HOST_DEVICE T fastExpOf(T x)
{
    using Ops = FastExpOps<T>;
    // One select per bound; NaN maps to -87, so the integer conversion in pow2 is always defined.
    const T below = Ops::select(x < 88.0f, x, Ops::splat(88.0f));
    x = Ops::select(x > -87.0f, below, Ops::splat(-87.0f));
    // n = round(x / ln 2) by the 1.5 * 2^23 trick: exact round-to-nearest without a rounding
    // instruction (SSE2 has none), valid for |x / ln 2| < 2^22.
    const T n = (x * 1.44269504088896341f + 12582912.0f) - 12582912.0f;
    // r = x - n ln 2 with ln 2 split in a short high part (n * hi is exact) and a correction.
    T r = x - n * 0.693359375f;
    r = r + n * 2.12194440e-4f;
    T p = Ops::splat(1.9875691500e-4f);
    p = p * r + 1.3981999507e-3f;
    p = p * r + 8.3334519073e-3f;
    p = p * r + 4.1665795894e-2f;
    p = p * r + 1.6666665459e-1f;
    p = p * r + 5.0000001201e-1f;
    p = p * (r * r) + r + 1.0f;
    return p * Ops::pow2(n);
}

/// @brief exp(x) for one float (see fastExpOf()).
SPLATWARP_HOST_DEVICE float fastExp(float x) { return fastExpOf(x); }

/// @brief exp in the precision of the argument: fastExp for float, std::exp for double (the
///        double-precision references of the tests keep the exact function).
SPLATWARP_HOST_DEVICE float expOf(float x) { return fastExp(x); }
SPLATWARP_HOST_DEVICE double expOf(double x) { return std::exp(x); }

} // namespace splatwarp
