#include "job/ValidationResiduals.h"

#include <algorithm>
#include <cmath>
#include <numeric>

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
void PointBuckets::forEachIn(const BucketRange& r, F&& f) const
{
    for (std::int64_t i = r.lo[0]; i <= r.hi[0]; ++i)
        for (std::int64_t j = r.lo[1]; j <= r.hi[1]; ++j)
            for (std::int64_t k = r.lo[2]; k <= r.hi[2]; ++k) {
                const std::size_t b = std::size_t(key(i, j, k));
                for (std::size_t q = mStart[b]; q < mStart[b + 1]; ++q) f(i, j, k, q);
            }
}

template <typename F>
void PointBuckets::forEachNear(const float* lo, const float* hi, F&& f) const
{
    forEachIn(rangeOf(lo, hi), [&](std::int64_t, std::int64_t, std::int64_t, std::size_t slot) { f(slot); });
}

ValidationResiduals::ValidationResiduals(const Judge& validation, const GaussianCloud& model)
    : mOptions(validation.points().features), mStride(model.shStride()), mBuckets(validation.points().warped, 64)
{
    // Every per-point array is kept in bucket order (slots), so a visit reads memory in order.
    const std::vector<float>& x = validation.points().warped;
    const FieldErrorTarget& t = validation.target();
    const std::size_t p = t.size(), stride = std::size_t(mStride);
    const std::shared_ptr<const Judge::Evaluation> evaluation = validation.evaluate(model);
    const std::vector<float>& f = evaluation->features;
    const std::vector<float>& o = evaluation->opacity;
    mWeightO = t.sumOpacity > 0 ? 1.0 / t.sumOpacity : 0.0;
    mWeightF = t.sumFeatures > 0 ? 1.0 / t.sumFeatures : 0.0;
    mX.resize(3 * p);
    mO.resize(p);
    mF.resize(f.size());
    mWeight.resize(p);
    mSlotOf.resize(p);
    for (std::size_t slot = 0; slot < p; ++slot) {
        const std::size_t j = mBuckets.pointAt(slot);
        mSlotOf[j] = slot;
        for (int a = 0; a < 3; ++a) mX[3 * slot + std::size_t(a)] = x[3 * j + std::size_t(a)];
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

/// One side of a swap: the prepared Gaussian, its SH and its box.
struct SwapSide {
    PreparedGaussian g;
    const float* sh;
    float lo[3], hi[3];

    SwapSide(GaussianRef r, const FeatureOptions& o)
        : g(prepareGaussian(*r.cloud, r.index, o.filterVariance, o.cutoff)), sh(r.cloud->shOf(r.index))
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

template <typename F>
void ValidationResiduals::visit(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in, F&& f) const
{
    std::vector<std::pair<SwapSide, double>> terms; // each side with its sign
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int side = 0; side < 2; ++side)
        for (const GaussianRef& r : side ? in : out) {
            terms.emplace_back(SwapSide(r, mOptions), side ? 1.0 : -1.0);
            terms.back().first.widen(lo, hi);
        }
    std::vector<double> dF(static_cast<std::size_t>(mStride));
    mBuckets.forEachNear(lo, hi, [&](std::size_t j) {
        const Vec3f x{mX[3 * j], mX[3 * j + 1], mX[3 * j + 2]};
        double dO = 0;
        bool any = false;
        std::fill(dF.begin(), dF.end(), 0.0);
        for (const auto& [t, sign] : terms) {
            const double w = double(t.g.weight(x - t.g.mean, mOptions.cutoff)) * sign;
            if (w == 0.0) continue;
            any = true;
            dO += w;
            for (int s = 0; s < mStride; ++s) dF[std::size_t(s)] += w * double(t.sh[s]);
        }
        if (any) f(j, dO, dF.data());
    });
}

double ValidationResiduals::change(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in) const
{
    double o = 0, c = 0;
    visit(out, in, [&](std::size_t j, double dO, const double* dF) {
        o += (std::fabs(mO[j] + dO) - std::fabs(mO[j])) * mWeight[j];
        const double* r = mF.data() + j * std::size_t(mStride);
        double cj = 0;
        for (int s = 0; s < mStride; ++s) cj += std::fabs(r[s] + dF[s]) - std::fabs(r[s]);
        c += cj * mWeight[j];
    });
    return o * mWeightO + c * mWeightF;
}

void ValidationResiduals::changes(GaussianRef out, const std::vector<GaussianRef>& ins, double* result) const
{
    // Each candidate reads the buckets of its own pair's box, as change() would: the same points
    // in the same order, so the same sums; the visit covers them all.
    const SwapSide o(out, mOptions);
    std::vector<SwapSide> in;
    std::vector<BucketRange> read;
    for (const GaussianRef& r : ins) {
        in.emplace_back(r, mOptions);
        read.push_back(unionRange(mBuckets, o, &in.back(), 1));
    }
    const std::size_t n = in.size(), stride = std::size_t(mStride);
    std::vector<double> sumO(n, 0.0), sumF(n, 0.0);
    mBuckets.forEachIn(unionRange(mBuckets, o, in.data(), in.size()), [&](std::int64_t bi, std::int64_t bj, std::int64_t bk, std::size_t j) {
        const Vec3f x{mX[3 * j], mX[3 * j + 1], mX[3 * j + 2]};
        const double wOut = double(o.g.weight(x - o.g.mean, mOptions.cutoff)) * -1.0;
        const double* r = mF.data() + j * stride;
        for (std::size_t c = 0; c < n; ++c) {
            if (!read[c].contains(bi, bj, bk)) continue;
            const double wIn = double(in[c].g.weight(x - in[c].g.mean, mOptions.cutoff));
            if (wOut == 0.0 && wIn == 0.0) continue;
            double dO = 0;
            if (wOut != 0.0) dO += wOut;
            if (wIn != 0.0) dO += wIn;
            sumO[c] += (std::fabs(mO[j] + dO) - std::fabs(mO[j])) * mWeight[j];
            double cj = 0;
            for (std::size_t s = 0; s < stride; ++s) {
                double dF = 0;
                if (wOut != 0.0) dF += wOut * double(o.sh[s]);
                if (wIn != 0.0) dF += wIn * double(in[c].sh[s]);
                cj += std::fabs(r[s] + dF) - std::fabs(r[s]);
            }
            sumF[c] += cj * mWeight[j];
        }
    });
    for (std::size_t c = 0; c < n; ++c) result[c] = sumO[c] * mWeightO + sumF[c] * mWeightF;
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
