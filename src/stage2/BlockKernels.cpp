#include "stage2/BlockKernels.h"

#include <cmath>
#include <cstring>

#include "core/FastExp.h"
#include "stage2/SampleBlocks.h"

namespace splatwarp {
namespace {

constexpr int L = kSimdLanes;
static_assert(L == 8, "chunk masks are bytes");

bool chunkOn(std::uint64_t mask, int t0) { return ((mask >> t0) & 0xffu) != 0; }

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

/// Sum of the lanes of an accumulator in a fixed order, in double.
inline __attribute__((always_inline)) double laneSum(VecF v)
{
    double s = 0;
    for (int l = 0; l < L; ++l) s += double(v[l]);
    return s;
}

/// One chunk of blockWeights(); Directions also writes A d. Returns the byte mask of the
/// chunk's counting lanes.
template <bool Directions>
inline __attribute__((always_inline)) unsigned weightChunk(const PreparedGaussian& g, const float* px, const float* py,
                                                           const float* pz, float cutoff, float* w, float* ax, float* ay,
                                                           float* az)
{
    const VecF dx = loadF(px) - g.mean.x, dy = loadF(py) - g.mean.y, dz = loadF(pz) - g.mean.z;
    const VecF ux = g.invL[0] * dx, uy = g.invL[1] * dx + g.invL[2] * dy, uz = g.invL[3] * dx + g.invL[4] * dy + g.invL[5] * dz;
    const VecF q = ux * ux + uy * uy + uz * uz;
    const VecI near = (absF(dx) <= g.halfExtent.x) & (absF(dy) <= g.halfExtent.y) & (absF(dz) <= g.halfExtent.z) &
                      (q <= g.radius2);
    bool any = false;
    for (int l = 0; l < L; ++l) any |= near[l] != 0;
    if (!any) { // the usual case far from the Gaussian: no exponential
        storeF(w, VecF{});
        if constexpr (Directions) storeF(ax, VecF{}), storeF(ay, VecF{}), storeF(az, VecF{});
        return 0;
    }
    const VecF v = g.alpha * fastExpOf(-0.5f * q);
    const VecI ok = near & (v >= cutoff);
    storeF(w, select(ok, v, VecF{}));
    if constexpr (Directions) {
        storeF(ax, select(ok, g.invL[0] * ux + g.invL[1] * uy + g.invL[3] * uz, VecF{}));
        storeF(ay, select(ok, g.invL[2] * uy + g.invL[4] * uz, VecF{}));
        storeF(az, select(ok, g.invL[5] * uz, VecF{}));
    }
    unsigned bits = 0;
    for (int l = 0; l < L; ++l) bits |= unsigned(ok[l] & 1) << l;
    return bits;
}

} // namespace

std::uint64_t chunksOf(std::uint64_t mask)
{
    std::uint64_t out = 0;
    for (int t0 = 0; t0 < 64; t0 += L)
        if (chunkOn(mask, t0)) out |= std::uint64_t(0xffu) << t0;
    return out;
}

SPLATWARP_SIMD_CLONES std::uint64_t blockWeights(const PreparedGaussian& g, const BlockPoints& b, float cutoff, float* w,
                                                 float* ax, float* ay, float* az, std::uint64_t chunks,
                                                 const CoverageSlabs* slabs)
{
    std::uint64_t mask = 0;
    // The Gaussian's box, widened far beyond the rounding of m +- h and of the lanes' p - m, so the
    // chunk test below only skips chunks whose every lane fails |p - m| <= h.
    float lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
        const float m = g.mean[a], h = g.halfExtent[a], slack = 1e-5f * (std::fabs(m) + std::fabs(h));
        lo[a] = m - h - slack;
        hi[a] = m + h + slack;
    }
    for (int t0 = 0; t0 < b.lanes; t0 += L) {
        if (!chunkOn(chunks, t0)) continue;
        if (b.chunkLo) { // a chunk wholly outside the Gaussian's box fails weight()'s first test in every lane
            const float* cl = b.chunkLo + 3 * (t0 / L);
            const float* ch = b.chunkHi + 3 * (t0 / L);
            if (ch[0] < lo[0] || cl[0] > hi[0] || ch[1] < lo[1] || cl[1] > hi[1] || ch[2] < lo[2] || cl[2] > hi[2]) continue;
            if (slabs && !boxMeetsSlabs(cl, ch, *slabs)) continue;
        }
        const unsigned bits = ax ? weightChunk<true>(g, b.px + t0, b.py + t0, b.pz + t0, cutoff, w + t0, ax + t0, ay + t0, az + t0)
                                 : weightChunk<false>(g, b.px + t0, b.py + t0, b.pz + t0, cutoff, w + t0, nullptr, nullptr,
                                                      nullptr);
        mask |= std::uint64_t(bits) << t0;
    }
    // Padding lanes repeat the last sample and may count: keep only the real samples.
    return b.samples >= 64 ? mask : mask & ((std::uint64_t(1) << b.samples) - 1);
}

SPLATWARP_SIMD_CLONES void blockAccumulate(const float* w, int lanes, std::uint64_t mask, const float* h, int stride, float* f,
                                           float* o)
{
    for (int t0 = 0; t0 < lanes; t0 += L) {
        if (!chunkOn(mask, t0)) continue;
        const VecF wv = loadF(w + t0);
        storeF(o + t0, loadF(o + t0) + wv);
        for (int c = 0; c < stride; ++c) {
            float* fc = f + c * lanes + t0;
            storeF(fc, loadF(fc) + wv * h[c]);
        }
    }
}

SPLATWARP_SIMD_CLONES void blockBackward(const float* w, const float* ax, const float* ay, const float* az, int lanes,
                                         std::uint64_t mask, const float* gF, const float* gO, const float* h, int stride,
                                         float alpha, BlockPairSums& sums)
{
    VecF mean[3] = {}, sigma[6] = {}, dAlpha = {}, sh[kMaxShStride];
    for (int c = 0; c < stride; ++c) sh[c] = VecF{};
    for (int t0 = 0; t0 < lanes; t0 += L) {
        if (!chunkOn(mask, t0)) continue;
        VecF gw = loadF(gO + t0);
        for (int c = 0; c < stride; ++c) gw = gw + loadF(gF + c * lanes + t0) * h[c];
        const VecF wl = loadF(w + t0), x = loadF(ax + t0), y = loadF(ay + t0), z = loadF(az + t0);
        const VecF gq = gw * wl; // see pairBackward()
        mean[0] += x * gq;
        mean[1] += y * gq;
        mean[2] += z * gq;
        const VecF hq = gq * 0.5f;
        sigma[0] += hq * x * x;
        sigma[1] += hq * x * y;
        sigma[2] += hq * x * z;
        sigma[3] += hq * y * y;
        sigma[4] += hq * y * z;
        sigma[5] += hq * z * z;
        dAlpha += gw * wl / alpha;
        for (int c = 0; c < stride; ++c) sh[c] += wl * loadF(gF + c * lanes + t0);
    }
    for (int a = 0; a < 3; ++a) sums.mean[a] += laneSum(mean[a]);
    for (int a = 0; a < 6; ++a) sums.sigma[a] += laneSum(sigma[a]);
    sums.alpha += laneSum(dAlpha);
    for (int c = 0; c < stride; ++c) sums.sh[c] += laneSum(sh[c]);
}

} // namespace splatwarp
