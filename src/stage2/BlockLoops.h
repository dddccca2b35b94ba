#pragma once
/// @file BlockLoops.h
/// @brief Stage II pair work of one Gaussian over one sample block (SampleBlocks.h), written as
///        plain loops over kSimdLanes-wide chunks that the compiler vectorises, built for AVX2
///        and the baseline with runtime dispatch (core/Simd.h). Per lane they do exactly what
///        PreparedGaussian::weight() and the scalar pair maths (PairGradients.h) do, in float.
///        A 64-bit lane mask says which lanes count; chunks whose lanes all fail the cheap tests
///        (box, Mahalanobis radius) skip the exponential, and the forward pass keeps the weights
///        of the chunks that count for the backward pass.
#include <cstddef>
#include <cstdint>

#include "core/Simd.h"
#include "field/PreparedGaussian.h"

namespace splatwarp {

/// Largest SH stride (degree 3: 16 coefficients x 3 channels).
constexpr int kMaxShStride = 48;

/// @brief A block's sample positions: `lanes` padded slots (a multiple of kSimdLanes, at most
///        64), of which the first `samples` are real.
struct BlockPoints {
    const float *px, *py, *pz; ///< [lanes]
    int lanes, samples;
    const float* chunks = nullptr; ///< [6, kSimdLanes] chunk centres and half sizes (SampleBlocks::chunks), or null
};

/// @brief What the chunk tests need of a Gaussian beyond PreparedGaussian, computed once per
///        Gaussian. A point p = c + e of a chunk (centre c, |e_a| <= half_a) has
///        |L^-1 (p - m)| >= |L^-1 (c - m)| - sum_a half_a |column a of L^-1|, so a chunk whose
///        bound exceeds sqrt(radius2) holds no lane where the Gaussian counts. All values are
///        grown by a relative and an absolute slack far beyond float rounding.
struct ChunkBound {
    float column[3] = {0, 0, 0}; ///< |column a of L^-1|, grown
    float slack[3] = {0, 0, 0};  ///< absolute slack added to a chunk's half size per axis
    float radius = -1;           ///< sqrt(radius2), grown (< 0: never counts)

    static ChunkBound of(const PreparedGaussian& g);
};

/// @brief The Gaussians listed for one block (ascending) and where their data is.
struct BlockGaussians {
    const std::uint32_t* items = nullptr; ///< [n] Gaussian indices
    std::size_t n = 0;
    const PreparedGaussian* prepared = nullptr; ///< indexed by Gaussian
    const ChunkBound* bounds = nullptr;        ///< indexed by Gaussian
    const float* sh = nullptr;                 ///< SH coefficients of Gaussian k at sh + k * shPitch
    std::size_t shPitch = 0;
};

/// @brief Every listed Gaussian's contribution to a block, in list order: f[c][t] += w[t] h[c],
///        o[t] += w[t] with w = alpha*G where the pair counts (exactly as
///        PreparedGaussian::weight(), 0 elsewhere). Chunks that miss a Gaussian's box or its
///        padded cutoff ellipsoid (ChunkBound) are skipped, all of a block's chunks tested at
///        once; the tests are conservative, so no counting lane is ever skipped. Padding lanes
///        of f and o are written but meaningless.
/// @param f  [stride][lanes]; o: [lanes]
/// @return the counting (real lane, Gaussian) pairs
std::uint64_t blockFeatures(const BlockGaussians& gs, const BlockPoints& b, float cutoff, int stride, float* f, float* o);

/// Floats a counting chunk keeps for the backward pass (blockForward): w, then A d x, y, z.
constexpr int kKeptChunkFloats = 4 * kSimdLanes;

/// @brief blockFeatures() that also keeps, for each pair, which chunks count (bit c: chunk c)
///        and their w and A d (kKeptChunkFloats floats each, chunks ascending), so the
///        backward pass need not evaluate the pair again.
/// @param chunks  out [n]; kept: room for n * lanes/kSimdLanes chunks; keptAt: out [n], where
///                each pair's kept chunks start
std::uint64_t blockForward(const BlockGaussians& gs, const BlockPoints& b, float cutoff, int stride, float* f, float* o,
                           std::uint8_t* chunks, float* kept, std::uint32_t* keptAt);

/// Backward sums of one (block, Gaussian) pair before its SH ones: dE/dmu 3, dE/dSigma' upper
/// triangle xx xy xz yy yz zz, dE/dalpha.
constexpr int kPairSums = 10;

/// @brief The backward sums of each counting pair of a block (pairBackward() per pair, per-lane
///        float partial sums, lanes reduced in double in a fixed order) from what blockForward()
///        kept, packed: only counting pairs take room (a pass counts about a quarter of the
///        coverage's pairs, and room per listed pair kept most pages of it resident).
/// @param gF  [stride][lanes] dE/dF; gO: [lanes] dE/dO (0 in padding)
/// @param partials  out [counting pairs, kPairSums + stride], in entry order: dE/dmu, dE/dSigma'
///                  (upper triangle), dE/dalpha, dE/dH
/// @param first     the slot of the block's first counting pair
/// @param slots     out [n]: each counting pair's slot (first, first + 1, ...); the others untouched
void blockBackward(const BlockGaussians& gs, int lanes, const std::uint8_t* chunks, const float* kept,
                   const std::uint32_t* keptAt, const float* gF, const float* gO, int stride, float* partials,
                   std::uint32_t first, std::uint32_t* slots);

/// @brief sums[c] += partials[slots[e] * pitch + c] in double for each entry e of `entries` in
///        order whose chunks[e] is not 0 (one Gaussian's pairs gathered in a fixed order).
void gatherPartials(const float* partials, std::size_t pitch, const std::uint32_t* slots, const std::uint32_t* entries,
                    std::size_t n, const std::uint8_t* chunks, double* sums);

/// @brief sampleLoss() on every lane of a block (the same operations per lane, so the same bits).
///        Lanes at or past `samples` get zero gradients and terms.
/// @param f, tF  [stride][lanes] current and target F; o, tO: [lanes]
/// @param gF     out [stride][lanes] dE/dF; gO: out [lanes]; terms: out [3][lanes] (see sampleLoss())
void blockLoss(const float* f, const float* o, const float* tF, const float* tO, int lanes, int samples, int stride,
               float lambda1, float lambda2, float* gF, float* gO, float* terms);

} // namespace splatwarp
