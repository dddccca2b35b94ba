/// The SH palette of SOG: k-means of each Gaussian's f_rest, started from distinct points chosen
/// with a seed (splat-transform seeds at random). Each Lloyd round labels every point with the
/// centroid a scan over all of them finds (the lowest index of the least float sum of squares,
/// summed in dimension order), so a palette is the same bytes on any machine and thread count.
/// Two things make that fast without changing a label: a ranking by matrix product narrows the
/// scan to the centroids it cannot separate from the best, and bounds kept between rounds
/// (Hamerly's) spare the points whose centroid cannot have changed. Past 4096 centroids (up to
/// 65536, splat-transform's size for a million Gaussians) a point searches only the groups of
/// centroids nearest it (GroupedSearch), by the same scan.
#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#include "core/Hash.h"
#include "core/Simd.h"
#include "io/SogFormat.h"

namespace splatwarp::sog {

namespace {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
constexpr float kInf = std::numeric_limits<float>::infinity();
// Up to this many centroids a label is the nearest of all; past it, the nearest in the kNearGroups
// groups of centroids nearest the point (GroupedSearch).
constexpr std::size_t kExactUpTo = 4096;
constexpr std::size_t kNearGroups = 4;

// splitmix64: a portable generator (std distributions differ between standard libraries).
struct SplitMix {
    std::uint64_t state;
    std::uint64_t next() { return mix64(state += 0x9e3779b97f4a7c15ull); }
    std::size_t below(std::size_t n) { return std::size_t(next() % n); }
};

// The slack, in units of (|x| + |c|)^2, that covers the ranking's rounding and the scan's for d
// dimensions (CentroidTable says why): 4 (d + 8) float epsilons.
float scanTolerance(std::size_t d) { return 4.0f * float(d + 8) * std::numeric_limits<float>::epsilon() / 2.0f; }

// The scan's distance: a float sum of squares in dimension order, left once it reaches `limit`
// (the sum only grows, so whether it ends below `limit` is the same).
float scanDistance(const float* x, const float* y, std::size_t d, float limit)
{
    float s = 0;
    for (std::size_t j = 0; j < d && s < limit; ++j) s += (x[j] - y[j]) * (x[j] - y[j]);
    return s;
}

double exactDistance(const float* x, const float* y, std::size_t d)
{
    double s = 0;
    for (std::size_t j = 0; j < d; ++j) s += (double(x[j]) - double(y[j])) * (double(x[j]) - double(y[j]));
    return std::sqrt(s);
}

// 16 floats as one value: one AVX-512 register, two AVX2 ones, four SSE ones (GCC and Clang).
typedef float Float16 __attribute__((vector_size(64)));
// 8 floats, one AVX2 register, for the selects (GCC spills 16-wide ones there).
typedef float Float8 __attribute__((vector_size(32)));
typedef std::int32_t Int8 __attribute__((vector_size(32)));

// The least of n values: four chains of lane-wise selects (so their latencies overlap) written
// with masks, which GCC keeps in vector registers where it spills a vector `?:`.
#define SPLATWARP_LESSER(a, b) Float8((Int8(a) & Int8((a) < (b))) | (Int8(b) & ~Int8((a) < (b))))
SPLATWARP_SIMD_CLONES float leastOf(const float* values, std::size_t n)
{
    Float8 least[4];
    for (Float8& l : least) l = kInf - Float8{};
    std::size_t i = 0;
    for (; i + 32 <= n; i += 32)
        for (int k = 0; k < 4; ++k) {
            Float8 v;
            std::memcpy(&v, values + i + 8 * std::size_t(k), sizeof v);
            least[k] = SPLATWARP_LESSER(v, least[k]);
        }
    least[0] = SPLATWARP_LESSER(least[0], least[1]);
    least[2] = SPLATWARP_LESSER(least[2], least[3]);
    least[0] = SPLATWARP_LESSER(least[0], least[2]);
    float result = kInf;
    for (int l = 0; l < 8; ++l) result = std::min(result, least[0][l]);
    for (; i < n; ++i) result = std::min(result, values[i]);
    return result;
}
#undef SPLATWARP_LESSER

// dots[p kPad + c] = x_p . c for the m points of x (rows of d floats; rows up to a multiple of 4
// readable) and the centroids of ct (tiles of 16 centroids, each d rows of their 16 coordinates j
// side by side, read in order; kPad a multiple of 16). Four points and sixteen centroids at a
// time, their sums in registers. Only the ranking uses it: its rounding may differ by clone.
SPLATWARP_SIMD_CLONES_ANY_ROUNDING void blockDots(
    const float* __restrict x, std::size_t m, std::size_t d, const float* __restrict ct, std::size_t kPad,
    float* __restrict dots)
{
    for (std::size_t p0 = 0; p0 < m; p0 += 4) {
        const float *x0 = x + p0 * d, *x1 = x0 + d, *x2 = x1 + d, *x3 = x2 + d;
        for (std::size_t c0 = 0; c0 < kPad; c0 += 16) {
            Float16 a0 = {}, a1 = {}, a2 = {}, a3 = {};
            for (std::size_t j = 0; j < d; ++j) {
                Float16 col;
                std::memcpy(&col, ct + c0 * d + j * 16, sizeof col);
                a0 += x0[j] * col;
                a1 += x1[j] * col;
                a2 += x2[j] * col;
                a3 += x3[j] * col;
            }
            const Float16* sums[4] = {&a0, &a1, &a2, &a3};
            for (std::size_t p = 0; p < 4 && p0 + p < m; ++p)
                std::memcpy(dots + (p0 + p) * kPad + c0, sums[p], sizeof(Float16));
        }
    }
}

// Each centroid's bounds on its scan distance past |x|^2: score -+ slack into `lo` and `hi`.
SPLATWARP_SIMD_CLONES void scoreBounds(const float* __restrict dots, const float* __restrict norm2,
                                       const float* __restrict norm, float xNorm, float tol, std::size_t k,
                                       float* __restrict lo, float* __restrict hi)
{
    for (std::size_t c = 0; c < k; ++c) {
        const float score = norm2[c] - 2.0f * dots[c];
        const float r = xNorm + norm[c], slack = tol * r * r;
        lo[c] = score - slack;
        hi[c] = score + slack;
    }
}

// Whether any of n values is at most `limit` (a vectorised skip over the bounds).
SPLATWARP_SIMD_CLONES bool anyBelow(const float* values, std::size_t n, float limit)
{
    int any = 0;
    for (std::size_t i = 0; i < n; ++i) any |= values[i] <= limit;
    return any != 0;
}

// The centroids as the ranking sees them: centred on their mean (so |x| and |c| stay near the
// distances they rank), with their norms. The ranking score |c|^2 - 2 x.c and the scan sum both
// stay within tol (|x| + |c|)^2 of |x|^2 + score: tol = 4 (d + 8) float epsilons, above the
// (3d + 8) that the bounds of the product, the centring and the sum add up to.
struct CentroidTable {
    CentroidTable(const std::vector<float>& centroids, std::size_t k, std::size_t d)
        : raw(centroids.data()), k(k), d(d), tol(scanTolerance(d))
    {
        const Eigen::Map<const RowMatrix> c(raw, Eigen::Index(k), Eigen::Index(d));
        mean = c.colwise().mean();
        centred = c.rowwise() - mean;
        norm.resize(k);
        norm2.resize(k);
        for (std::size_t i = 0; i < k; ++i) {
            norm2[i] = float(centred.row(Eigen::Index(i)).cast<double>().squaredNorm());
            norm[i] = std::sqrt(norm2[i]);
        }
        kPad = (k + 15) / 16 * 16;
        columns.assign(d * kPad, 0.0f);
        for (std::size_t i = 0; i < k; ++i)
            for (std::size_t j = 0; j < d; ++j)
                columns[(i / 16 * d + j) * 16 + i % 16] = centred(Eigen::Index(i), Eigen::Index(j));
    }
    const float* raw;
    std::size_t k, d;
    float tol;
    std::size_t kPad = 0;
    Eigen::RowVectorXf mean;
    RowMatrix centred;
    std::vector<float> columns; ///< [kPad / 16, d, 16]: the centred centroids in tiles of 16, coordinates side by side
    std::vector<float> norm, norm2;
};

// Scans, in index order, the centroids whose lower bound is under the least upper one; keeps
// `label` when none is nearer than infinity, as the scan does. Returns the winner's scan sum.
float nearestOf(const CentroidTable& t, const float* x, const std::vector<float>& lo, const std::vector<float>& hi,
                std::uint32_t& label)
{
    constexpr std::size_t kChunk = 64;
    const float upper = leastOf(hi.data(), t.k);
    float best = kInf;
    for (std::size_t c0 = 0; c0 < t.k; c0 += kChunk) {
        const std::size_t c1 = std::min(t.k, c0 + kChunk);
        if (!anyBelow(lo.data() + c0, c1 - c0, upper)) continue;
        for (std::size_t c = c0; c < c1; ++c) {
            if (!(lo[c] <= upper)) continue;
            const float d = scanDistance(x, t.raw + c * t.d, t.d, best);
            if (d < best) best = d, label = std::uint32_t(c);
        }
    }
    return best;
}

// The q centroids of least scan sum (ties to the lower index), nearest first: at least q have
// an upper bound under the q-th least one, so the q nearest all have lower bounds under it.
void nearestFew(const CentroidTable& t, const float* x, const std::vector<float>& lo, const std::vector<float>& hi,
                std::size_t q, std::vector<std::pair<float, std::uint32_t>>& few, std::uint32_t* out)
{
    few.assign(q, {kInf, 0}); // the q least upper bounds, ascending
    for (std::size_t c = 0; c < t.k; ++c)
        if (hi[c] < few[q - 1].first) {
            std::size_t at = q - 1;
            for (; at > 0 && few[at - 1].first > hi[c]; --at) few[at] = few[at - 1];
            few[at].first = hi[c];
        }
    const float limit = few[q - 1].first;
    few.clear();
    for (std::size_t c = 0; c < t.k; ++c)
        if (lo[c] <= limit) few.emplace_back(scanDistance(x, t.raw + c * t.d, t.d, kInf), std::uint32_t(c));
    const std::size_t m = std::min(q, few.size()); // fewer only where sums overflow to NaN
    std::partial_sort(few.begin(), few.begin() + std::ptrdiff_t(m), few.end());
    for (std::size_t i = 0; i < q; ++i) out[i] = m == 0 ? 0 : few[std::min(i, m - 1)].second; // a repeat is harmless
}

// Ranks the centroids of `t` for blocks of listed points: visit(position in the list, the point,
// its squared norm as the ranking centres it, lo, hi) for each, lo and hi bounding each
// centroid's scan sum less that norm, in the thread's scratch. In parallel.
struct RankScratch {
    RowMatrix x, dots;
    std::vector<float> lo, hi;
    std::vector<std::pair<float, std::uint32_t>> few;
};
template <class Visit>
void rankEach(const float* points, std::size_t d, const std::vector<std::uint32_t>& index, const CentroidTable& t,
              const Visit& visit)
{
    const std::size_t rows = std::clamp<std::size_t>((std::size_t(1) << 17) / t.k, 8, 256) / 4 * 4; // dots in L2
    tbb::enumerable_thread_specific<RankScratch> scratch;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, index.size(), rows), [&](const tbb::blocked_range<std::size_t>& r) {
        RankScratch& s = scratch.local(); // sized once: fresh pages each block cost more than the product
        if (s.lo.empty()) {
            s.x.setZero(Eigen::Index(rows), Eigen::Index(d));
            s.dots.resize(Eigen::Index(rows), Eigen::Index(t.kPad));
            s.lo.resize(t.k);
            s.hi.resize(t.k);
        }
        for (std::size_t b = r.begin(); b < r.end(); b += rows) { // the partitioner may hand out more
            const std::size_t m = std::min(r.end() - b, rows);
            for (std::size_t i = 0; i < m; ++i)
                s.x.row(Eigen::Index(i)) = Eigen::Map<const Eigen::RowVectorXf>(points + index[b + i] * d, Eigen::Index(d)) - t.mean;
            blockDots(s.x.data(), m, d, t.columns.data(), t.kPad, s.dots.data());
            for (std::size_t i = 0; i < m; ++i) {
                const double x2 = s.x.row(Eigen::Index(i)).cast<double>().squaredNorm();
                scoreBounds(s.dots.row(Eigen::Index(i)).data(), t.norm2.data(), t.norm.data(), float(std::sqrt(x2)),
                            t.tol, t.k, s.lo.data(), s.hi.data());
                visit(b + i, points + index[b + i] * d, x2, s);
            }
        }
    });
}

// Every point's label, and bounds on its true distance to its centroid (upper) and to every other
// centroid (lower). Between rounds the bounds move by the centroids' drift; a point whose upper
// bound stays below its lower one, by more than the scan's rounding, keeps its label unsearched.
class LabelSearch {
public:
    LabelSearch(const std::vector<float>& points, std::size_t n, std::size_t d)
        : mPoints(points.data()), mN(n), mD(d), mUpper(n, kInf), mLower(n, 0.0)
    {
    }

    void assignAll(Palette& p)
    {
        std::vector<std::uint32_t> all(mN);
        std::iota(all.begin(), all.end(), std::uint32_t(0));
        search(all, p);
    }

    // After the centroids moved from `previous`.
    void reassign(const std::vector<float>& previous, Palette& p)
    {
        std::vector<double> drift(p.count);
        for (std::size_t c = 0; c < p.count; ++c)
            drift[c] = exactDistance(&previous[c * mD], &p.centroids[c * mD], mD) * (1 + 1e-9);
        const std::size_t far = std::size_t(std::max_element(drift.begin(), drift.end()) - drift.begin());
        double second = 0;
        for (std::size_t c = 0; c < p.count; ++c)
            if (c != far) second = std::max(second, drift[c]);
        const float tol = scanTolerance(mD);
        std::vector<std::uint8_t> open(mN, 0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mN, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i < r.end(); ++i) {
                const std::uint32_t a = p.labels[i];
                mUpper[i] += drift[a];
                mLower[i] -= a == far ? second : drift[far];
                if (separated(mUpper[i], mLower[i], tol)) continue;
                mUpper[i] = exactDistance(mPoints + i * mD, &p.centroids[a * mD], mD) * (1 + 1e-9);
                open[i] = !separated(mUpper[i], mLower[i], tol);
            }
        });
        std::vector<std::uint32_t> todo;
        for (std::size_t i = 0; i < mN; ++i)
            if (open[i]) todo.push_back(std::uint32_t(i));
        search(todo, p);
    }

private:
    // Every other centroid is farther, also by the scan's sums (each within tol of the truth).
    static bool separated(double upper, double lower, float tol)
    {
        return lower > 0 && upper * upper * (1 + double(tol)) < lower * lower * (1 - double(tol));
    }

    void search(const std::vector<std::uint32_t>& todo, Palette& p)
    {
        const CentroidTable t(p.centroids, p.count, mD);
        rankEach(mPoints, mD, todo, t, [&](std::size_t i, const float* x, double x2, RankScratch& s) {
            const std::uint32_t j = todo[i];
            if (!(nearestOf(t, x, s.lo, s.hi, p.labels[j]) < kInf)) {
                mUpper[j] = kInf, mLower[j] = 0; // sums beyond float: never skipped
                return;
            }
            const std::size_t a = p.labels[j];
            const float other = std::min(leastOf(s.lo.data(), a), leastOf(s.lo.data() + a + 1, t.k - a - 1));
            mUpper[j] = std::sqrt(std::max(0.0, x2 + double(s.hi[a])));
            mLower[j] = std::sqrt(std::max(0.0, x2 + double(other)));
        });
    }

    const float* mPoints;
    std::size_t mN, mD;
    std::vector<double> mUpper, mLower;
};

// Palettes past kExactUpTo entries: each point takes the nearest centroid among those of the
// kNearGroups groups whose centres are nearest it, the centroids grouped by a small k-means of
// them (about sqrt(K) a group). A point then ranks an eighth to a thirty-second of the palette;
// its label may miss a nearer centroid in a farther group. Every choice is by the scan's sums,
// so the palette is the same bytes on any machine and thread count.
class GroupedSearch {
public:
    GroupedSearch(const std::vector<float>& points, std::size_t n, std::size_t d, std::uint64_t seed)
        : mPoints(points), mN(n), mD(d), mSeed(seed)
    {
    }

    void assign(Palette& p)
    {
        const Palette groups = kmeans(p.centroids, p.count, int(mD), groupCount(p.count), kGroupRounds, mSeed);
        const std::size_t q = std::min(groups.count, kNearGroups);
        const std::vector<std::uint32_t> near = nearGroups(groups, q);
        std::vector<std::vector<std::uint32_t>> members(groups.count), visitors(groups.count);
        for (std::size_t c = 0; c < p.count; ++c) members[groups.labels[c]].push_back(std::uint32_t(c));
        for (std::size_t i = 0; i < mN * q; ++i) // once per group (nearestFew repeats one where sums are NaN)
            if (std::find(&near[i - i % q], &near[i], near[i]) == &near[i]) visitors[near[i]].push_back(std::uint32_t(i / q));
        std::vector<std::pair<float, std::uint32_t>> best(mN * q, {kInf, 0}); // per point and near group
        tbb::parallel_for(std::size_t(0), groups.count, [&](std::size_t g) {
            if (visitors[g].empty() || members[g].empty()) return;
            std::vector<float> rows(members[g].size() * mD);
            for (std::size_t c = 0; c < members[g].size(); ++c)
                std::copy_n(&p.centroids[members[g][c] * mD], mD, &rows[c * mD]);
            const CentroidTable table(rows, members[g].size(), mD);
            rankEach(mPoints.data(), mD, visitors[g], table, [&](std::size_t v, const float* x, double, RankScratch& s) {
                const std::size_t i = visitors[g][v], r = std::size_t(std::find(&near[i * q], &near[i * q] + q, g) - &near[i * q]);
                std::uint32_t local = 0;
                const float sum = nearestOf(table, x, s.lo, s.hi, local);
                best[i * q + r] = {sum, members[g][local]};
            });
        });
        tbb::parallel_for(std::size_t(0), mN, [&](std::size_t i) {
            const auto least = *std::min_element(&best[i * q], &best[i * q] + q); // ties to the lower index
            if (least.first < kInf) p.labels[i] = least.second;
        });
    }

private:
    static constexpr int kGroupRounds = 4;
    static std::size_t groupCount(std::size_t k) { return std::size_t(std::lround(std::sqrt(double(k)))); }

    // Each point's q nearest group centres, [n, q].
    std::vector<std::uint32_t> nearGroups(const Palette& groups, std::size_t q) const
    {
        std::vector<std::uint32_t> all(mN), near(mN * q);
        std::iota(all.begin(), all.end(), std::uint32_t(0));
        const CentroidTable table(groups.centroids, groups.count, mD);
        rankEach(mPoints.data(), mD, all, table, [&](std::size_t i, const float* x, double, RankScratch& s) {
            nearestFew(table, x, s.lo, s.hi, q, s.few, &near[i * q]);
        });
        return near;
    }

    const std::vector<float>& mPoints;
    std::size_t mN, mD;
    std::uint64_t mSeed;
};

// Centroids to the means of their points, in a fixed order (the same sums on any thread count).
void updateCentroids(const std::vector<float>& points, std::size_t n, std::size_t d, Palette& p, SplitMix& rng)
{
    std::vector<double> sums(p.count * d, 0.0);
    std::vector<std::size_t> counts(p.count, 0);
    for (std::size_t i = 0; i < n; ++i) {
        ++counts[p.labels[i]];
        for (std::size_t j = 0; j < d; ++j) sums[p.labels[i] * d + j] += points[i * d + j];
    }
    for (std::size_t c = 0; c < p.count; ++c) {
        if (counts[c] == 0) { // an empty cluster restarts at a point
            std::copy_n(&points[rng.below(n) * d], d, &p.centroids[c * d]);
            continue;
        }
        for (std::size_t j = 0; j < d; ++j) p.centroids[c * d + j] = float(sums[c * d + j] / double(counts[c]));
    }
}

} // namespace

Palette kmeans(const std::vector<float>& points, std::size_t n, int dims, std::size_t k, int iterations,
               std::uint64_t seed)
{
    const std::size_t d = std::size_t(dims);
    Palette p;
    p.count = std::max<std::size_t>(1, std::min(k, n));
    p.centroids.resize(p.count * d);
    SplitMix rng{seed};
    std::vector<std::size_t> pick(n);
    std::iota(pick.begin(), pick.end(), std::size_t(0));
    for (std::size_t i = 0; i < p.count; ++i) { // partial Fisher-Yates: distinct starting points
        std::swap(pick[i], pick[i + rng.below(n - i)]);
        std::copy_n(&points[pick[i] * d], d, &p.centroids[i * d]);
    }
    p.labels.assign(n, 0);
    if (p.count > kExactUpTo) {
        GroupedSearch search(points, n, d, seed);
        search.assign(p);
        for (int it = 0; it < iterations; ++it) {
            updateCentroids(points, n, d, p, rng);
            search.assign(p);
        }
        return p;
    }
    LabelSearch search(points, n, d);
    search.assignAll(p);
    for (int it = 0; it < iterations; ++it) {
        const std::vector<float> previous = p.centroids;
        updateCentroids(points, n, d, p, rng);
        search.reassign(previous, p); // labels always name their nearest final centroid
    }
    return p;
}

} // namespace splatwarp::sog
