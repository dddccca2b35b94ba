/// The SH palette of SOG: k-means of each Gaussian's f_rest, started from distinct points chosen
/// with a seed (splat-transform seeds at random). Each Lloyd round labels every point with the
/// centroid a scan over all of them finds (the lowest index of the least float sum of squares,
/// summed in dimension order), so a palette is the same bytes on any machine and thread count.
/// Two things make that fast without changing a label: a ranking by matrix product narrows the
/// scan to the centroids it cannot separate from the best, and bounds kept between rounds
/// (Hamerly's) spare the points whose centroid cannot have changed.
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
    static constexpr std::size_t kChunk = 64;
    struct Scratch {
        RowMatrix x, dots;
        std::vector<float> lo, hi;
    };

    // Every other centroid is farther, also by the scan's sums (each within tol of the truth).
    static bool separated(double upper, double lower, float tol)
    {
        return lower > 0 && upper * upper * (1 + double(tol)) < lower * lower * (1 - double(tol));
    }

    void search(const std::vector<std::uint32_t>& todo, Palette& p)
    {
        const CentroidTable table(p.centroids, p.count, mD);
        const std::size_t rows = std::clamp<std::size_t>((std::size_t(1) << 17) / p.count, 8, 256) / 4 * 4; // dots in L2
        tbb::enumerable_thread_specific<Scratch> scratch;
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, todo.size(), rows), [&](const tbb::blocked_range<std::size_t>& r) {
            Scratch& s = scratch.local(); // sized once: fresh pages each block cost more than the product
            if (s.lo.empty()) {
                s.x.setZero(Eigen::Index(rows), Eigen::Index(mD));
                s.dots.resize(Eigen::Index(rows), Eigen::Index(table.kPad));
                s.lo.resize(p.count);
                s.hi.resize(p.count);
            }
            for (std::size_t b = r.begin(); b < r.end(); b += rows) // the partitioner may hand out more
                searchBlock(table, &todo[b], std::min(r.end() - b, rows), s, p.labels.data());
        });
    }

    void searchBlock(const CentroidTable& t, const std::uint32_t* index, std::size_t m, Scratch& s,
                     std::uint32_t* labels)
    {
        for (std::size_t i = 0; i < m; ++i)
            s.x.row(Eigen::Index(i)) = Eigen::Map<const Eigen::RowVectorXf>(mPoints + index[i] * mD, Eigen::Index(mD)) - t.mean;
        blockDots(s.x.data(), m, mD, t.columns.data(), t.kPad, s.dots.data());
        for (std::size_t i = 0; i < m; ++i) {
            const double x2 = s.x.row(Eigen::Index(i)).cast<double>().squaredNorm();
            scoreBounds(s.dots.row(Eigen::Index(i)).data(), t.norm2.data(), t.norm.data(), float(std::sqrt(x2)), t.tol,
                        t.k, s.lo.data(), s.hi.data());
            const std::size_t j = index[i];
            if (!nearest(t, mPoints + j * mD, s, labels[j])) {
                mUpper[j] = kInf, mLower[j] = 0; // sums beyond float: never skipped
                continue;
            }
            const std::size_t a = labels[j];
            const float other = std::min(leastOf(s.lo.data(), a), leastOf(s.lo.data() + a + 1, t.k - a - 1));
            mUpper[j] = std::sqrt(std::max(0.0, x2 + double(s.hi[a])));
            mLower[j] = std::sqrt(std::max(0.0, x2 + double(other)));
        }
    }

    // Scans, in index order, the centroids whose lower bound is under the least upper one; keeps
    // `label` when none is nearer than infinity, as the scan does (then returns false).
    static bool nearest(const CentroidTable& t, const float* x, const Scratch& s, std::uint32_t& label)
    {
        const float upper = leastOf(s.hi.data(), t.k);
        float best = kInf;
        for (std::size_t c0 = 0; c0 < t.k; c0 += kChunk) {
            const std::size_t c1 = std::min(t.k, c0 + kChunk);
            if (!anyBelow(s.lo.data() + c0, c1 - c0, upper)) continue;
            for (std::size_t c = c0; c < c1; ++c) {
                if (!(s.lo[c] <= upper)) continue;
                const float d = scanDistance(x, t.raw + c * t.d, t.d, best);
                if (d < best) best = d, label = std::uint32_t(c);
            }
        }
        return best < kInf;
    }

    const float* mPoints;
    std::size_t mN, mD;
    std::vector<double> mUpper, mLower;
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
