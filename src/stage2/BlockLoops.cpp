#include "stage2/BlockLoops.h"

#include <cmath>
#include <cstring>

#include "core/FastExp.h"
#include "stage2/SampleBlocks.h"

namespace splatwarp {
namespace {

constexpr int L = kSimdLanes;
static_assert(L == 8, "chunk masks are bytes");

// One chunk of kSimdLanes lanes as GCC vector types: explicit SIMD that compiles to AVX2 in the
// avx2 clone and to pairs of SSE2 registers in the baseline one, with no reliance on the
// auto-vectoriser. Each lane does the scalar operations of PreparedGaussian::weight() and
// fastExp() in the same order, so the bits are the same.
typedef float VecF __attribute__((vector_size(4 * L)));
typedef std::int32_t VecI __attribute__((vector_size(4 * L)));

inline __attribute__((always_inline)) VecF loadF(const float* p)
{
    VecF v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
inline __attribute__((always_inline)) void storeF(float* p, VecF v) { std::memcpy(p, &v, sizeof v); }
inline __attribute__((always_inline)) VecF splat(float x) { return VecF{} + x; }
inline __attribute__((always_inline)) VecF absF(VecF v) { return (VecF)((VecI)v & 0x7fffffff); }
inline __attribute__((always_inline)) VecF select(VecI m, VecF a, VecF b) { return (VecF)((m & (VecI)a) | (~m & (VecI)b)); }

} // namespace

/// fastExpOf() on SIMD lanes (core/FastExp.h): the scalar operations per lane, so the same bits.
template <>
struct FastExpOps<VecF> {
    static VecF splat(float v) { return splatwarp::splat(v); }
    static VecF select(VecI m, VecF a, VecF b) { return splatwarp::select(m, a, b); }
    static VecF pow2(VecF n) { return (VecF)((__builtin_convertvector(n, VecI) + 127) << 23); }
};

namespace {

typedef float VecF4 __attribute__((vector_size(16)));
typedef double VecD4 __attribute__((vector_size(32)));

/// Lanes l and l + 4 of v added in double.
inline __attribute__((always_inline)) VecD4 halves(VecF v)
{
    return __builtin_convertvector(__builtin_shufflevector(v, v, 0, 1, 2, 3), VecD4) +
           __builtin_convertvector(__builtin_shufflevector(v, v, 4, 5, 6, 7), VecD4);
}

/// Sum of the lanes of an accumulator in double, in a fixed order:
/// ((l0 + l4) + (l1 + l5)) + ((l2 + l6) + (l3 + l7)).
inline __attribute__((always_inline)) double laneSum(VecF v)
{
    const VecD4 h = halves(v);
    return (h[0] + h[1]) + (h[2] + h[3]);
}

/// laneSum() of n accumulators rounded to float, four at a time by a transpose (same order).
inline __attribute__((always_inline)) void laneSums(const VecF* acc, int n, float* out)
{
    int i = 0;
    for (; i + 4 <= n; i += 4) {
        const VecD4 s0 = halves(acc[i]), s1 = halves(acc[i + 1]), s2 = halves(acc[i + 2]), s3 = halves(acc[i + 3]);
        const VecD4 t0 = __builtin_shufflevector(s0, s1, 0, 4, 2, 6) + __builtin_shufflevector(s0, s1, 1, 5, 3, 7);
        const VecD4 t1 = __builtin_shufflevector(s2, s3, 0, 4, 2, 6) + __builtin_shufflevector(s2, s3, 1, 5, 3, 7);
        const VecD4 u = __builtin_shufflevector(t0, t1, 0, 1, 4, 5) + __builtin_shufflevector(t0, t1, 2, 3, 6, 7);
        const VecF4 f = __builtin_convertvector(u, VecF4);
        std::memcpy(out + i, &f, sizeof f);
    }
    for (; i < n; ++i) out[i] = float(laneSum(acc[i]));
}

/// Bit l set where lane l of m is set (m: 0 or -1 per lane).
inline __attribute__((always_inline)) unsigned bitsOf(VecI m)
{
    typedef std::int32_t VecI4 __attribute__((vector_size(16)));
    const VecI b = m & VecI{1, 2, 4, 8, 16, 32, 64, 128};
    VecI4 r = __builtin_shufflevector(b, b, 0, 1, 2, 3) | __builtin_shufflevector(b, b, 4, 5, 6, 7);
    r |= __builtin_shufflevector(r, r, 2, 3, 0, 1);
    r |= __builtin_shufflevector(r, r, 1, 0, 3, 2);
    return unsigned(r[0]);
}

/// One chunk of a pair: alpha*G where it counts (0 elsewhere, exactly as weight()) in w, and the
/// lanes that count in ok (0 in every lane when none is near: no exponential); with Keep, also
/// A d at kept + L (x, y, z rows of L lanes).
template <bool Keep>
inline __attribute__((always_inline)) bool weightChunk(const PreparedGaussian& g, const float* px, const float* py,
                                                       const float* pz, float cutoff, VecF& w, VecI& ok, float* kept)
{
    const VecF dx = loadF(px) - g.mean.x, dy = loadF(py) - g.mean.y, dz = loadF(pz) - g.mean.z;
    const VecF ux = g.invL[0] * dx, uy = g.invL[1] * dx + g.invL[2] * dy, uz = g.invL[3] * dx + g.invL[4] * dy + g.invL[5] * dz;
    const VecF q = ux * ux + uy * uy + uz * uz;
    const VecI near = (absF(dx) <= g.halfExtent.x) & (absF(dy) <= g.halfExtent.y) & (absF(dz) <= g.halfExtent.z) &
                      (q <= g.radius2);
    if (bitsOf(near) == 0) return false; // the usual case far from the Gaussian: no exponential
    const VecF v = g.alpha * fastExpOf(-0.5f * q);
    ok = near & (v >= cutoff);
    w = select(ok, v, VecF{});
    if constexpr (Keep) {
        storeF(kept + L, select(ok, g.invL[0] * ux + g.invL[1] * uy + g.invL[3] * uz, VecF{}));
        storeF(kept + 2 * L, select(ok, g.invL[2] * uy + g.invL[4] * uz, VecF{}));
        storeF(kept + 3 * L, select(ok, g.invL[5] * uz, VecF{}));
    }
    return true;
}

/// Relative slack of the chunk tests, far beyond the float rounding of the lanes' p - m, u and q.
constexpr float kChunkSlack = 1e-4f;
constexpr float kGrow = 1.0f + kChunkSlack;

/// A block's chunk bounds in registers (one lane per chunk), loaded once for all its Gaussians.
struct ChunkRows {
    VecF cx, cy, cz, hx, hy, hz; ///< centres; half sizes grown by kGrow
    unsigned all;                ///< bits of the block's chunks

    explicit ChunkRows(const BlockPoints& b)
    {
        all = b.lanes >= 64 ? 0xffu : (1u << (b.lanes / L)) - 1u;
        if (!b.chunks) return;
        const float* c = b.chunks;
        cx = loadF(c), cy = loadF(c + L), cz = loadF(c + 2 * L);
        hx = loadF(c + 3 * L) * kGrow, hy = loadF(c + 4 * L) * kGrow, hz = loadF(c + 5 * L) * kGrow;
    }
};

/// Bit c set for each chunk c of the block that may hold a lane where g counts: those meeting
/// its box and its padded ellipsoid (ChunkBound), all chunks of a block tested at once.
inline __attribute__((always_inline)) unsigned liveChunks(const PreparedGaussian& g, const ChunkBound& cb, const BlockPoints& b,
                                                          const ChunkRows& rows)
{
    if (!(cb.radius >= 0.0f)) return 0; // never counts (weight() fails q <= radius2 everywhere)
    if (!b.chunks) return rows.all;
    const float* iv = g.invL;
    const VecF ex = rows.hx + cb.slack[0], ey = rows.hy + cb.slack[1], ez = rows.hz + cb.slack[2];
    const VecF dx = rows.cx - g.mean.x, dy = rows.cy - g.mean.y, dz = rows.cz - g.mean.z;
    const VecI box = (absF(dx) <= ex + g.halfExtent.x) & (absF(dy) <= ey + g.halfExtent.y) & (absF(dz) <= ez + g.halfExtent.z);
    const VecF ux = iv[0] * dx, uy = iv[1] * dx + iv[2] * dy, uz = iv[3] * dx + iv[4] * dy + iv[5] * dz;
    const VecF reach = ex * cb.column[0] + ey * cb.column[1] + ez * cb.column[2] + cb.radius;
    return bitsOf(box & (ux * ux + uy * uy + uz * uz <= reach * reach)) & rows.all;
}

/// The real (not padding) lanes of the chunk at t0.
inline __attribute__((always_inline)) VecI realLanes(const BlockPoints& b, int t0)
{
    return VecI{0, 1, 2, 3, 4, 5, 6, 7} < b.samples - t0;
}

/// One pair's forward over a block: the weights of each live chunk, added to F and O where a
/// real lane counts (the whole chunk, as padding lanes are never read); `counted` gains the
/// counting lanes. With Keep the counting chunks' w and A d go to `kept`.
/// @return bit c set for each chunk c with a counting lane
template <bool Keep>
inline __attribute__((always_inline)) unsigned forwardPair(const PreparedGaussian& g, const ChunkBound& cb, const BlockPoints& b,
                                                           const ChunkRows& rows, float cutoff, const float* h, int stride,
                                                           float* f, float* o, float* kept, VecI& counted)
{
    unsigned chunks = 0;
    const int lanes = b.lanes;
    for (unsigned live = liveChunks(g, cb, b, rows); live != 0; live &= live - 1) {
        const int c = __builtin_ctz(live), t0 = c * L;
        VecF w = {};
        VecI ok = {};
        if (!weightChunk<Keep>(g, b.px + t0, b.py + t0, b.pz + t0, cutoff, w, ok, kept)) continue;
        // Padding lanes repeat the last sample and may count: they are not counted.
        const VecI real = ok & realLanes(b, t0);
        if (bitsOf(real) == 0) continue; // a kept slot is reused by the next chunk
        counted -= real;
        chunks |= 1u << c;
        storeF(o + t0, loadF(o + t0) + w);
        for (int k = 0; k < stride; ++k) {
            float* fk = f + k * lanes + t0;
            storeF(fk, loadF(fk) + w * h[k]);
        }
        if constexpr (Keep) {
            storeF(kept, w);
            kept += kKeptChunkFloats;
        }
    }
    return chunks;
}

inline __attribute__((always_inline)) std::uint64_t laneTotal(VecI v)
{
    std::uint64_t s = 0;
    for (int l = 0; l < L; ++l) s += std::uint64_t(std::uint32_t(v[l]));
    return s;
}

} // namespace

ChunkBound ChunkBound::of(const PreparedGaussian& g)
{
    ChunkBound cb;
    if (!(g.radius2 >= 0.0f)) return cb;
    const float* iv = g.invL; // rows 00 | 10 11 | 20 21 22
    cb.column[0] = kGrow * std::sqrt(iv[0] * iv[0] + iv[1] * iv[1] + iv[3] * iv[3]);
    cb.column[1] = kGrow * std::sqrt(iv[2] * iv[2] + iv[4] * iv[4]);
    cb.column[2] = kGrow * std::fabs(iv[5]);
    for (int a = 0; a < 3; ++a) cb.slack[a] = kChunkSlack * (std::fabs(g.mean[a]) + std::fabs(g.halfExtent[a]));
    cb.radius = kGrow * std::sqrt(g.radius2);
    return cb;
}

SPLATWARP_SIMD_CLONES std::uint64_t blockFeatures(const BlockGaussians& gs, const BlockPoints& b, float cutoff, int stride,
                                                  float* f, float* o)
{
    const ChunkRows rows(b);
    VecI counted = {};
    for (std::size_t i = 0; i < gs.n; ++i) {
        const std::uint32_t k = gs.items[i];
        forwardPair<false>(gs.prepared[k], gs.bounds[k], b, rows, cutoff, gs.sh + k * gs.shPitch, stride, f, o, nullptr, counted);
    }
    return laneTotal(counted);
}

SPLATWARP_SIMD_CLONES std::uint64_t blockForward(const BlockGaussians& gs, const BlockPoints& b, float cutoff, int stride,
                                                 float* f, float* o, std::uint8_t* chunks, float* kept, std::uint32_t* keptAt)
{
    const ChunkRows rows(b);
    VecI counted = {};
    std::uint32_t used = 0;
    for (std::size_t i = 0; i < gs.n; ++i) {
        const std::uint32_t k = gs.items[i];
        keptAt[i] = used;
        const unsigned c = forwardPair<true>(gs.prepared[k], gs.bounds[k], b, rows, cutoff, gs.sh + k * gs.shPitch, stride, f, o,
                                             kept + used, counted);
        chunks[i] = std::uint8_t(c);
        used += std::uint32_t(__builtin_popcount(c)) * kKeptChunkFloats;
    }
    return laneTotal(counted);
}

namespace {

/// The backward sums of one pair from its kept chunks (see blockBackward()).
inline __attribute__((always_inline)) void backwardPair(const float* kept, unsigned chunks, int lanes, const float* gF,
                                                        const float* gO, const float* h, int stride, float alpha, float* out)
{
    // Accumulators: dE/dmu 3, dE/dSigma' 6, sum of dE/dw w (dE/dalpha times alpha), then dE/dH.
    VecF acc[kPairSums + kMaxShStride];
    for (int c = 0; c < kPairSums + stride; ++c) acc[c] = VecF{};
    VecF* sh = acc + kPairSums;
    for (; chunks != 0; chunks &= chunks - 1) {
        const int t0 = __builtin_ctz(chunks) * L;
        VecF gw = loadF(gO + t0);
        for (int c = 0; c < stride; ++c) gw = gw + loadF(gF + c * lanes + t0) * h[c];
        const VecF wl = loadF(kept), x = loadF(kept + L), y = loadF(kept + 2 * L), z = loadF(kept + 3 * L);
        kept += kKeptChunkFloats;
        const VecF gq = gw * wl; // see pairBackward()
        acc[0] += x * gq;
        acc[1] += y * gq;
        acc[2] += z * gq;
        const VecF hq = gq * 0.5f;
        acc[3] += hq * x * x;
        acc[4] += hq * x * y;
        acc[5] += hq * x * z;
        acc[6] += hq * y * y;
        acc[7] += hq * y * z;
        acc[8] += hq * z * z;
        acc[9] += gq;
        for (int c = 0; c < stride; ++c) sh[c] += wl * loadF(gF + c * lanes + t0);
    }
    laneSums(acc, 9, out);
    out[9] = float(laneSum(acc[9]) / double(alpha));
    laneSums(sh, stride, out + kPairSums);
}

} // namespace

SPLATWARP_SIMD_CLONES void blockBackward(const BlockGaussians& gs, int lanes, const std::uint8_t* chunks, const float* kept,
                                         const std::uint32_t* keptAt, const float* gF, const float* gO, int stride,
                                         float* partials, std::uint32_t first, std::uint32_t* slots)
{
    const std::size_t pitch = std::size_t(kPairSums + stride);
    std::uint32_t slot = first;
    for (std::size_t i = 0; i < gs.n; ++i) {
        if (chunks[i] == 0) continue;
        const std::uint32_t k = gs.items[i];
        backwardPair(kept + keptAt[i], chunks[i], lanes, gF, gO, gs.sh + k * gs.shPitch, stride, gs.prepared[k].alpha,
                     partials + std::size_t(slot - first) * pitch);
        slots[i] = slot++;
    }
}

SPLATWARP_SIMD_CLONES void gatherPartials(const float* partials, std::size_t pitch, const std::uint32_t* slots,
                                          const std::uint32_t* entries, std::size_t n, const std::uint8_t* chunks,
                                          double* sums)
{
    const std::size_t wide = pitch / 4 * 4;
    for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t e = entries[i];
        if (chunks[e] == 0) continue;
        const float* in = partials + std::size_t(slots[e]) * pitch;
        for (std::size_t c = 0; c < wide; c += 4) {
            VecF4 v;
            std::memcpy(&v, in + c, sizeof v);
            VecD4 d;
            std::memcpy(&d, sums + c, sizeof d);
            d += __builtin_convertvector(v, VecD4);
            std::memcpy(sums + c, &d, sizeof d);
        }
        for (std::size_t c = wide; c < pitch; ++c) sums[c] += double(in[c]);
    }
}

namespace {

inline __attribute__((always_inline)) VecF signOf(VecF v)
{
    return select(v > 0.0f, splat(1.0f), select(v < 0.0f, splat(-1.0f), VecF{}));
}

} // namespace

SPLATWARP_SIMD_CLONES void blockLoss(const float* f, const float* o, const float* tF, const float* tO, int lanes, int samples,
                                     int stride, float lambda1, float lambda2, float* gF, float* gO, float* terms)
{
    const VecI lane = {0, 1, 2, 3, 4, 5, 6, 7};
    for (int t0 = 0; t0 < lanes; t0 += L) {
        const VecI real = lane + t0 < samples;
        VecF e = {};
        for (int c = 0; c < stride; ++c) {
            const VecF r = loadF(f + c * lanes + t0) - loadF(tF + c * lanes + t0);
            e += absF(r);
            storeF(gF + c * lanes + t0, select(real, signOf(r), VecF{}));
        }
        const VecF target = loadF(tO + t0), ro = loadF(o + t0) - target, aro = absF(ro);
        const VecI empty = target == 0.0f;
        const VecF weight = lambda1 + select(empty, splat(lambda2), VecF{});
        storeF(gO + t0, select(real, weight * signOf(ro), VecF{}));
        storeF(terms + t0, select(real, e, VecF{}));
        storeF(terms + lanes + t0, select(real, lambda1 * aro, VecF{}));
        storeF(terms + 2 * lanes + t0, select(real & empty, lambda2 * aro, VecF{}));
    }
}

} // namespace splatwarp
