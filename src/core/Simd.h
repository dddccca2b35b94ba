#pragma once
/// @file Simd.h
/// @brief Runtime dispatch for the vectorised inner loops: GCC function multi-versioning
///        compiles a marked function for AVX2 and for the baseline, and the loader picks the
///        best one the processor has (one binary for every x86-64 machine). Without floating
///        point contraction (the build is strict ISO C++, so -ffp-contract=off) both versions do
///        the same IEEE operations per lane, so results do not depend on the machine.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(__CUDACC__) && \
    !defined(SPLATWARP_NO_SIMD_CLONES)
#define SPLATWARP_SIMD_CLONES __attribute__((target_clones("avx2", "default")))
/// Also AVX-512 (which brings FMA): only for loops whose rounding may differ between machines,
/// such as a ranking that an exact comparison settles afterwards.
#define SPLATWARP_SIMD_CLONES_ANY_ROUNDING __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define SPLATWARP_SIMD_CLONES
#define SPLATWARP_SIMD_CLONES_ANY_ROUNDING
#endif

namespace splatwarp {

/// Lanes the block loops are written for (8 floats = one AVX2 register); sample blocks are
/// padded to a multiple of it.
constexpr int kSimdLanes = 8;

} // namespace splatwarp
