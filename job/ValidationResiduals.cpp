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

template <typename F>
void PointBuckets::forEachNear(const float* lo, const float* hi, F&& f) const
{
    std::int64_t c0[3], c1[3];
    for (int a = 0; a < 3; ++a) {
        const double l = std::floor((double(lo[a]) - mLo[a]) / mCell), h = std::floor((double(hi[a]) - mLo[a]) / mCell);
        if (!(h >= 0 && l <= double(mCount[a] - 1))) return; // also refuses NaN bounds
        c0[a] = l < 0 ? 0 : std::int64_t(l);
        c1[a] = h > double(mCount[a] - 1) ? mCount[a] - 1 : std::int64_t(h);
    }
    for (std::int64_t i = c0[0]; i <= c1[0]; ++i)
        for (std::int64_t j = c0[1]; j <= c1[1]; ++j)
            for (std::int64_t k = c0[2]; k <= c1[2]; ++k) {
                const std::size_t b = std::size_t(key(i, j, k));
                for (std::size_t r = mStart[b]; r < mStart[b + 1]; ++r) f(mOrder[r]);
            }
}

ValidationResiduals::ValidationResiduals(const Judge& validation, const GaussianCloud& model)
    : mX(validation.points().warped), mOptions(validation.points().features), mStride(model.shStride()),
      mBuckets(mX, 64)
{
    const FieldErrorTarget& t = validation.target();
    const std::size_t p = t.size();
    std::vector<float> f(p * std::size_t(mStride)), o(p);
    evaluatePointsOn(model, mX.data(), p, mOptions, f.data(), o.data()); // the block engine on the CPU: same bits
    mO.resize(p);
    mF.resize(f.size());
    for (std::size_t j = 0; j < p; ++j) mO[j] = double(o[j]) - double(t.opacity[j]);
    for (std::size_t k = 0; k < f.size(); ++k) mF[k] = double(f[k]) - t.features[k];
    mWeightO = t.sumOpacity > 0 ? 1.0 / t.sumOpacity : 0.0;
    mWeightF = t.sumFeatures > 0 ? 1.0 / t.sumFeatures : 0.0;
    mWeight.resize(p);
    for (std::size_t j = 0; j < p; ++j) mWeight[j] = t.weightOf(j);
}

double ValidationResiduals::score() const
{
    double o = 0, f = 0;
    for (std::size_t j = 0; j < mO.size(); ++j) {
        o += std::fabs(mO[j]) * mWeight[j];
        for (int s = 0; s < mStride; ++s) f += std::fabs(mF[j * std::size_t(mStride) + std::size_t(s)]) * mWeight[j];
    }
    return o * mWeightO + f * mWeightF;
}

template <typename F>
void ValidationResiduals::visit(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in, F&& f) const
{
    struct Term {
        PreparedGaussian g;
        const float* sh;
        double sign;
    };
    std::vector<Term> terms;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int side = 0; side < 2; ++side)
        for (const GaussianRef& r : side ? in : out) {
            Term t{prepareGaussian(*r.cloud, r.index, mOptions.filterVariance, mOptions.cutoff), r.cloud->shOf(r.index),
                   side ? 1.0 : -1.0};
            float l[3], h[3];
            preparedBox(t.g, l, h);
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], l[k]);
                hi[k] = std::max(hi[k], h[k]);
            }
            terms.push_back(t);
        }
    std::vector<double> dF(static_cast<std::size_t>(mStride));
    mBuckets.forEachNear(lo, hi, [&](std::size_t j) {
        const Vec3f x{mX[3 * j], mX[3 * j + 1], mX[3 * j + 2]};
        double dO = 0;
        bool any = false;
        std::fill(dF.begin(), dF.end(), 0.0);
        for (const Term& t : terms) {
            const double w = double(t.g.weight(x - t.g.mean, mOptions.cutoff)) * t.sign;
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

void ValidationResiduals::apply(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in)
{
    visit(out, in, [&](std::size_t j, double dO, const double* dF) {
        mO[j] += dO;
        double* r = mF.data() + j * std::size_t(mStride);
        for (int s = 0; s < mStride; ++s) r[s] += dF[s];
    });
}

} // namespace splatwarp
