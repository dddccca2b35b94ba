#pragma once
/// @file BlockKernels.h
/// @brief Stage II pair work of one Gaussian over one sample block (SampleBlocks.h), written as
///        plain loops over kSimdLanes-wide chunks that the compiler vectorises, built for AVX2
///        and the baseline with runtime dispatch (core/Simd.h). Per lane they do exactly what
///        PreparedGaussian::weight() and the scalar pair maths (PairGradients.h) do, in float.
///        A 64-bit lane mask says which lanes count; chunks whose lanes all fail the cheap tests
///        (box, Mahalanobis radius) skip the exponential, and the backward pass visits only the
///        chunks the forward pass found counting.
#include <cstdint>

#include "core/Simd.h"
#include "stage2/Coverage.h"
#include "field/PreparedGaussian.h"

namespace splatwarp {

/// Largest SH stride (degree 3: 16 coefficients x 3 channels).
constexpr int kMaxShStride = 48;

/// @brief A block's sample positions: `lanes` padded slots (a multiple of kSimdLanes, at most
///        64), of which the first `samples` are real.
struct BlockPoints {
    const float *px, *py, *pz; ///< [lanes]
    int lanes, samples;
    const float *chunkLo = nullptr, *chunkHi = nullptr; ///< [lanes/kSimdLanes, 3] chunk bounds, or null
};

/// @brief Mask of the lanes of the chunks holding any lane of `mask` (each chunk kSimdLanes wide).
std::uint64_t chunksOf(std::uint64_t mask);

/// @brief alpha*G of g at the lanes of the chunks in `chunks` (0 where the pair does not
///        count, exactly as PreparedGaussian::weight(); lanes of other chunks are left alone);
///        with ax/ay/az non-null also A d (0 where it does not count).
///        With `slabs` (slabs holding every point where g can count, e.g. its own axes), chunks
///        whose bounds miss them are skipped too.
/// @return the mask of the real samples' lanes that count
std::uint64_t blockWeights(const PreparedGaussian& g, const BlockPoints& b, float cutoff, float* w, float* ax = nullptr,
                           float* ay = nullptr, float* az = nullptr, std::uint64_t chunks = ~std::uint64_t(0),
                           const CoverageSlabs* slabs = nullptr);

/// @brief Forward accumulation f[c][t] += w[t] h[c], o[t] += w[t] over the chunks holding `mask`.
/// @param f  [stride][lanes]; o: [lanes]
void blockAccumulate(const float* w, int lanes, std::uint64_t mask, const float* h, int stride, float* f, float* o);

/// @brief A Gaussian's backward sums over its pairs (dE/dmu, dE/dSigma' upper triangle
///        xx xy xz yy yz zz, dE/dalpha, dE/dH), in double across blocks.
struct BlockPairSums {
    double mean[3] = {0, 0, 0};
    double sigma[6] = {0, 0, 0, 0, 0, 0};
    double alpha = 0;
    double sh[kMaxShStride] = {};
};

/// @brief Add one block's pairs of a Gaussian to its backward sums (pairBackward() per pair,
///        per-lane float partial sums reduced in a fixed order), over the chunks holding `mask`.
/// @param w, ax, ay, az  from blockWeights(); gF: [stride][lanes] dE/dF; gO: [lanes] dE/dO (0 in padding)
void blockBackward(const float* w, const float* ax, const float* ay, const float* az, int lanes, std::uint64_t mask,
                   const float* gF, const float* gO, const float* h, int stride, float alpha, BlockPairSums& sums);

} // namespace splatwarp
