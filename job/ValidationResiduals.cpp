#include "job/ValidationResiduals.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/Error.h"
#include "core/Simd.h"
#include "stage2/BlockFeatures.h"
#include "field/PreparedGaussian.h"

namespace splatwarp {

PointLattice::PointLattice(const std::vector<float>& x, int cellsAlong)
{
    for (int a = 0; a < 3; ++a) {
        lo[a] = INFINITY;
        hi[a] = -INFINITY;
        for (std::size_t j = std::size_t(a); j < x.size(); j += 3) {
            lo[a] = std::min(lo[a], double(x[j]));
            hi[a] = std::max(hi[a], double(x[j]));
        }
        cell = std::max(cell, (hi[a] - lo[a]) / cellsAlong);
    }
    if (!(cell > 0)) cell = 1.0;
}

PointBuckets::PointBuckets(const std::vector<float>& x, int cellsAlong)
{
    const std::size_t n = x.size() / 3;
    const PointLattice lattice(x, cellsAlong);
    mCell = lattice.cell;
    for (int a = 0; a < 3; ++a) {
        mLo[a] = lattice.lo[a];
        mCount[a] = n ? std::int64_t(std::floor((lattice.hi[a] - mLo[a]) / mCell)) + 1 : 1;
    }
    // A counting sort: dense buckets (at most cellsAlong^3), points in index order within one.
    std::vector<std::int64_t> keys(n);
    mStart.assign(std::size_t(mCount[0] * mCount[1] * mCount[2]) + 1, 0);
    for (std::size_t j = 0; j < n; ++j) {
        keys[j] = key(cellOf(x[3 * j], 0), cellOf(x[3 * j + 1], 1), cellOf(x[3 * j + 2], 2));
        ++mStart[std::size_t(keys[j]) + 1];
    }
    std::partial_sum(mStart.begin(), mStart.end(), mStart.begin());
    std::vector<std::size_t> next(mStart.begin(), mStart.end() - 1);
    mOrder.resize(n);
    for (std::size_t j = 0; j < n; ++j) mOrder[next[std::size_t(keys[j])]++] = j;
}

std::int64_t PointBuckets::cellOf(double x, int a) const
{
    return std::clamp<std::int64_t>(std::int64_t(std::floor((x - mLo[a]) / mCell)), 0, mCount[a] - 1);
}

BucketRange PointBuckets::rangeOf(const float* lo, const float* hi) const
{
    BucketRange r;
    for (int a = 0; a < 3; ++a) {
        const double l = std::floor((double(lo[a]) - mLo[a]) / mCell), h = std::floor((double(hi[a]) - mLo[a]) / mCell);
        if (!(h >= 0 && l <= double(mCount[a] - 1))) return BucketRange{}; // also refuses NaN bounds
        r.lo[a] = l < 0 ? 0 : std::int64_t(l);
        r.hi[a] = h > double(mCount[a] - 1) ? mCount[a] - 1 : std::int64_t(h);
    }
    return r;
}

template <typename F>
void PointBuckets::forEachRun(const BucketRange& r, F&& f) const
{
    for (std::int64_t i = r.lo[0]; i <= r.hi[0]; ++i)
        for (std::int64_t j = r.lo[1]; j <= r.hi[1]; ++j)
            f(mStart[std::size_t(key(i, j, r.lo[2]))], mStart[std::size_t(key(i, j, r.hi[2])) + 1]);
}

ValidationResiduals::ValidationResiduals(const Judge& validation, const GaussianCloud& model)
    : mOptions(validation.points().features), mStride(model.shStride()), mBuckets(validation.points().warped, 64)
{
    // Every per-point array is kept in bucket order (slots), so a visit reads memory in order.
    const std::vector<float>& x = validation.points().warped;
    const FieldErrorTarget& t = validation.target();
    const std::size_t p = t.size(), stride = std::size_t(mStride);
    if (p > 0xffffffffull) throw InputError(msg("validation residuals: ", p, " points; at most 2^32 - 1"));
    const std::shared_ptr<const Judge::Evaluation> evaluation = validation.evaluate(model);
    const std::vector<float>& f = evaluation->features;
    const std::vector<float>& o = evaluation->opacity;
    mWeightO = t.sumOpacity > 0 ? 1.0 / t.sumOpacity : 0.0;
    mWeightF = t.sumFeatures > 0 ? 1.0 / t.sumFeatures : 0.0;
    for (auto& axis : mX) axis.resize(p);
    mO.resize(p);
    mF.resize(f.size());
    mWeight.resize(p);
    mSlotOf.resize(p);
    for (std::size_t slot = 0; slot < p; ++slot) {
        const std::size_t j = mBuckets.pointAt(slot);
        mSlotOf[j] = slot;
        for (int a = 0; a < 3; ++a) mX[a][slot] = x[3 * j + std::size_t(a)];
        mO[slot] = double(o[j]) - double(t.opacity[j]);
        for (std::size_t k = 0; k < stride; ++k) mF[slot * stride + k] = double(f[j * stride + k]) - t.features[j * stride + k];
        mWeight[slot] = t.weightOf(j);
    }
}

double ValidationResiduals::score() const
{
    double o = 0, f = 0;
    for (std::size_t j = 0; j < mO.size(); ++j) { // in the points' order, as the judge sums
        const std::size_t slot = mSlotOf[j];
        o += std::fabs(mO[slot]) * mWeight[slot];
        for (int s = 0; s < mStride; ++s) f += std::fabs(mF[slot * std::size_t(mStride) + std::size_t(s)]) * mWeight[slot];
    }
    return o * mWeightO + f * mWeightF;
}

namespace {

/// One side of a swap: the prepared Gaussian and its box.
struct SwapSide {
    PreparedGaussian g;
    float lo[3], hi[3];

    SwapSide(GaussianRef r, const FeatureOptions& o) : g(prepareGaussian(*r.cloud, r.index, o.filterVariance, o.cutoff))
    {
        preparedBox(g, lo, hi);
    }
    void widen(float* boxLo, float* boxHi) const
    {
        for (int k = 0; k < 3; ++k) {
            boxLo[k] = std::min(boxLo[k], lo[k]);
            boxHi[k] = std::max(boxHi[k], hi[k]);
        }
    }
};

/// The buckets of the box holding every side's box (the points a swap among them can change).
BucketRange unionRange(const PointBuckets& buckets, const SwapSide& out, const SwapSide* in, std::size_t n)
{
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    out.widen(lo, hi);
    for (std::size_t k = 0; k < n; ++k) in[k].widen(lo, hi);
    return buckets.rangeOf(lo, hi);
}

} // namespace

namespace {

/// Marks the points of a run [n] that may hold weight of g: inside its box and its padded
/// Mahalanobis radius (grown far beyond rounding, so the exact test after it decides). No branch
/// per point: the loop vectorises, where most points of a box miss the ellipsoid (guitar: 4%).
SPLATWARP_SIMD_CLONES
void markNear(const PreparedGaussian& g, const float* x, const float* y, const float* z, std::size_t n, std::int32_t* near)
{
    const float r2 = g.radius2 * 1.001f + 1e-6f;
    for (std::size_t q = 0; q < n; ++q) {
        const float dx = x[q] - g.mean.x, dy = y[q] - g.mean.y, dz = z[q] - g.mean.z;
        const float ux = g.invL[0] * dx, uy = g.invL[1] * dx + g.invL[2] * dy, uz = g.invL[3] * dx + g.invL[4] * dy + g.invL[5] * dz;
        near[q] = (std::fabs(dx) <= g.halfExtent.x) & (std::fabs(dy) <= g.halfExtent.y) & (std::fabs(dz) <= g.halfExtent.z) &
                  (ux * ux + uy * uy + uz * uz <= r2);
    }
}

} // namespace

template <typename Side>
void ValidationResiduals::hitsOf(const Side& side, std::uint32_t term, std::vector<Hit>& hits) const
{
    // The points of the buckets the side's box meets, run by run, each marked near or not at once,
    // then weighed as PreparedGaussian::weight() does: slots ascend.
    const PreparedGaussian& g = side.g;
    const float* x = mX[0].data();
    const float* y = mX[1].data();
    const float* z = mX[2].data();
    thread_local std::vector<std::int32_t> near;
    mBuckets.forEachRun(mBuckets.rangeOf(side.lo, side.hi), [&](std::size_t first, std::size_t end) {
        if (near.size() < end - first) near.resize(end - first);
        markNear(g, x + first, y + first, z + first, end - first, near.data());
        for (std::size_t q = first; q < end; ++q) {
            if (!near[q - first]) continue;
            const float w = g.weight(Vec3f{x[q], y[q], z[q]} - g.mean, mOptions.cutoff);
            if (w != 0.0f) hits.push_back({std::uint32_t(q), term, w});
        }
    });
}

void ValidationResiduals::sideHits(const std::vector<GaussianRef>& sides, std::vector<Hit>& hits,
                                   std::vector<const float*>& sh) const
{
    hits.clear();
    for (const GaussianRef& r : sides) {
        hitsOf(SwapSide(r, mOptions), std::uint32_t(sh.size()), hits);
        sh.push_back(r.cloud->shOf(r.index));
    }
    if (sides.size() > 1)
        std::sort(hits.begin(), hits.end(), [](const Hit& x, const Hit& y) { return x.slot != y.slot ? x.slot < y.slot : x.term < y.term; });
}

template <typename F>
void ValidationResiduals::forEachPoint(const std::vector<Hit>& out, const std::vector<Hit>& in, std::size_t outs,
                                       const std::vector<const float*>& sh, F&& f) const
{
    // Point by point (slots ascending) the sides that count there in term order, out before in (in's
    // terms follow out's): a point no side reaches changes nothing and is not visited.
    thread_local std::vector<double> dF;
    dF.assign(std::size_t(mStride), 0.0);
    std::size_t a = 0, b = 0;
    const auto add = [&](const Hit& h) {
        const double w = double(h.w) * (h.term < outs ? -1.0 : 1.0);
        const float* c = sh[h.term];
        for (int s = 0; s < mStride; ++s) dF[std::size_t(s)] += w * double(c[s]);
        return w;
    };
    while (a < out.size() || b < in.size()) {
        const std::uint32_t j = b == in.size() || (a < out.size() && out[a].slot <= in[b].slot) ? out[a].slot : in[b].slot;
        double dO = 0;
        std::fill(dF.begin(), dF.end(), 0.0);
        for (; a < out.size() && out[a].slot == j; ++a) dO += add(out[a]);
        for (; b < in.size() && in[b].slot == j; ++b) dO += add(in[b]);
        f(j, dO, dF.data());
    }
}

template <typename F>
void ValidationResiduals::visit(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in, F&& f) const
{
    thread_local std::vector<Hit> outHits, inHits;
    std::vector<const float*> sh;
    sideHits(out, outHits, sh);
    sideHits(in, inHits, sh);
    forEachPoint(outHits, inHits, out.size(), sh, f);
}

double ValidationResiduals::change(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in) const
{
    double result = 0;
    changes(out, {in}, &result);
    return result;
}

void ValidationResiduals::changes(const std::vector<GaussianRef>& out, const std::vector<std::vector<GaussianRef>>& ins,
                                  double* result, std::size_t* points) const
{
    // out's hits found once, each candidate's merged with them: the points and sums of change(out,
    // in) for each, one at a time.
    thread_local std::vector<Hit> outHits, inHits;
    std::vector<const float*> sh;
    sideHits(out, outHits, sh);
    for (std::size_t c = 0; c < ins.size(); ++c) {
        sh.resize(out.size());
        sideHits(ins[c], inHits, sh);
        double o = 0, f = 0;
        std::size_t visited = 0;
        forEachPoint(outHits, inHits, out.size(), sh, [&](std::size_t j, double dO, const double* dF) {
            ++visited;
            o += (std::fabs(mO[j] + dO) - std::fabs(mO[j])) * mWeight[j];
            const double* r = mF.data() + j * std::size_t(mStride);
            double cj = 0;
            for (int s = 0; s < mStride; ++s) cj += std::fabs(r[s] + dF[s]) - std::fabs(r[s]);
            f += cj * mWeight[j];
        });
        result[c] = o * mWeightO + f * mWeightF;
        if (points) points[c] = visited;
    }
}

BucketRange ValidationResiduals::reads(GaussianRef out, const std::vector<GaussianRef>& ins) const
{
    std::vector<SwapSide> in;
    for (const GaussianRef& r : ins) in.emplace_back(r, mOptions);
    return unionRange(mBuckets, SwapSide(out, mOptions), in.data(), in.size());
}

void ValidationResiduals::apply(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in)
{
    visit(out, in, [&](std::size_t j, double dO, const double* dF) {
        mO[j] += dO;
        double* r = mF.data() + j * std::size_t(mStride);
        for (int s = 0; s < mStride; ++s) r[s] += dF[s];
    });
}

} // namespace splatwarp
