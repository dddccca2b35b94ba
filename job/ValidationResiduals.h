#pragma once
/// @file ValidationResiduals.h
/// @brief A model's residuals at the validation points (its features minus the rest target's) and
///        the exact change of the validation score (Judge::score(): opacity + colour relative L1)
///        when some of its Gaussians are replaced by others. The field is a plain sum over
///        Gaussians, so a swap changes only the points the old and new cutoff boxes reach.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "job/Judge.h"
#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief Gaussian `index` of `cloud`.
struct GaussianRef {
    const GaussianCloud* cloud = nullptr;
    std::size_t index = 0;
};

/// @brief The bounds of points [P,3] and the cell edge that puts `cellsAlong` cells along their
///        largest extent (1 when they have no extent): the lattices the Stage II choices lay over
///        the validation points.
struct PointLattice {
    PointLattice(const std::vector<float>& points, int cellsAlong);
    double lo[3], hi[3];
    double cell = 0.0;
};

/// @brief A box of buckets [lo, hi] per axis (empty: lo > hi on some axis).
struct BucketRange {
    std::int64_t lo[3] = {0, 0, 0}, hi[3] = {-1, -1, -1};
};

/// @brief The validation points bucketed in a uniform grid, to visit the ones near a box.
class PointBuckets {
public:
    PointBuckets(const std::vector<float>& points, int cellsAlong);
    /// The buckets overlapping [lo, hi] (empty when the box misses the grid or is NaN).
    BucketRange rangeOf(const float* lo, const float* hi) const;
    /// Buckets along axis a.
    std::int64_t count(int a) const { return mCount[a]; }
    /// The point at a slot: slots number the points bucket by bucket, in index order within one.
    std::size_t pointAt(std::size_t slot) const { return mOrder[slot]; }
    /// Calls f(first, end) for each run of slots the buckets of r hold: a run per (i, j), its
    /// buckets along k being adjacent slots. Runs ascend, so slots do.
    template <typename F>
    void forEachRun(const BucketRange& r, F&& f) const;

private:
    std::int64_t cellOf(double x, int a) const;
    std::int64_t key(std::int64_t i, std::int64_t j, std::int64_t k) const { return (i * mCount[1] + j) * mCount[2] + k; }

    double mLo[3] = {0, 0, 0};
    double mCell = 0.0;
    std::int64_t mCount[3] = {1, 1, 1};
    std::vector<std::size_t> mOrder; ///< point indices by bucket (in index order within one)
    std::vector<std::size_t> mStart; ///< [buckets + 1]: bucket b holds mOrder[mStart[b], mStart[b + 1])
};

/// @brief See the file comment.
class ValidationResiduals {
public:
    ValidationResiduals(const Judge& validation, const GaussianCloud& model);
    /// The validation score of the model with every swap applied so far.
    double score() const;
    /// The score change if the Gaussians `out` (of the current model) are replaced by `in`.
    double change(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in) const;
    /// Record that swap.
    void apply(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in);
    /// change(out, ins[c]) for each c into result[c], the same bits, out's hits found once; with
    /// `points`, the number of points that swap changes (out's or ins[c]'s reach) into points[c].
    void changes(const std::vector<GaussianRef>& out, const std::vector<std::vector<GaussianRef>>& ins,
                 double* result, std::size_t* points = nullptr) const;
    /// The buckets changes(out, ins) reads; apply({out}, {one of ins}) writes within them.
    BucketRange reads(GaussianRef out, const std::vector<GaussianRef>& ins) const;
    /// Buckets along axis a.
    std::int64_t bucketsAlong(int a) const { return mBuckets.count(a); }

private:
    /// Where one Gaussian counts: a point's slot, the Gaussian's term in a swap, its weight there.
    struct Hit {
        std::uint32_t slot, term;
        float w;
    };

    template <typename F>
    void visit(const std::vector<GaussianRef>& out, const std::vector<GaussianRef>& in, F&& f) const;
    template <typename Side>
    void hitsOf(const Side& side, std::uint32_t term, std::vector<Hit>& hits) const;
    /// The hits of `sides` into hits (terms numbered on from sh.size(), whose SH they append),
    /// slots ascending, then terms.
    void sideHits(const std::vector<GaussianRef>& sides, std::vector<Hit>& hits, std::vector<const float*>& sh) const;
    /// f(slot, dO, dF) at each point out's or in's hits reach: the signed sums of their weights.
    template <typename F>
    void forEachPoint(const std::vector<Hit>& out, const std::vector<Hit>& in, std::size_t outs,
                      const std::vector<const float*>& sh, F&& f) const;

    std::vector<float> mX[3]; ///< [P] per axis, by slot (PointBuckets::pointAt), as every array below
    FeatureOptions mOptions;
    int mStride;
    PointBuckets mBuckets;
    std::vector<double> mO, mF; ///< [P], [P,stride]
    std::vector<double> mWeight; ///< [P] each point's weight (the target's) over the normalising sums
    std::vector<std::size_t> mSlotOf; ///< [P] each point's slot
    double mWeightO = 0, mWeightF = 0;
};

} // namespace splatwarp
