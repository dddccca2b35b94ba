#include "stage2/StageTwoCommon.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "core/Error.h"
#include "field/FeatureField.h"

namespace splatwarp {

namespace {

/// Relative allowance for the float rounding of the coverage tests (|n . (x - c)| and the box
/// comparisons on coordinates of this size): a few hundred float ulps.
constexpr double kCoverageRounding = 1e-5;

/// The Mahalanobis radius a prepared Gaussian's pruning tests allow (prepareGaussian pads it).
double prunedRadius(double r)
{
    return std::max(r * (1 + kPrunePad), std::sqrt(r * r * (1 + kPrunePad) + kPrunePad));
}

double support(const Mat3d& cov, const Vec3d& n, double radius)
{
    double q = 0;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) q += n[a] * cov.m[a][b] * n[b];
    return radius * std::sqrt(std::max(q, 0.0));
}

} // namespace

void stageTwoCoverageSlabs(const GaussianParams<double>& p, const Mat3d& filter, int steps, double move,
                           const StageTwoOptions& o, CoverageSlabs& out)
{
    const StageTwoReach r = stageTwoReach(p, filter, steps, move, o);
    const Mat3d rot = quatToMatrix(p.rotation);
    for (int a = 0; a < 3; ++a) {
        out.centre[a] = float(p.mean[a]);
        const Vec3d n(rot.m[0][a], rot.m[1][a], rot.m[2][a]);
        for (int b = 0; b < 3; ++b) out.axis[a][b] = float(n[b]);
        // The pruning pad and the rounding allowance keep the Gaussian as it is now inside
        // (stageTwoCoverageHolds) even with no learning rate at all.
        const double h = stageTwoReachWidth(r, n, support(r.cov, n, prunedRadius(r.radius)), o);
        out.half[a] = float(h < 0 ? h : h * (1 + kCoverageRounding) + kCoverageRounding * r.sphere);
    }
}

bool stageTwoCoverageHolds(const GaussianParams<double>& p, const Mat3d& filter, double cutoff, const float* lo,
                           const float* hi, const CoverageSlabs& slabs)
{
    const Vec3d sc(std::exp(p.logScale.x), std::exp(p.logScale.y), std::exp(p.logScale.z));
    const Mat3d cov = filteredCovariance(p.rotation, sc, filter);
    const double r = extentRadius(sigmoid(p.logit), cutoff);
    if (!(r > 0)) return true; // never counts (prepareGaussian leaves it empty)
    // Box: weight() tests the float AABB mean +- halfExtent first, so a counted pair lies in it.
    const Vec3d half = ellipsoidHalfExtent(cov, r * (1 + kPrunePad));
    for (int a = 0; a < 3; ++a) {
        const double h = half[a] * (1 + kCoverageRounding);
        if (!(p.mean[a] - h >= double(lo[a]) && p.mean[a] + h <= double(hi[a]))) return false;
    }
    // Slabs: a counted pair lies in the padded ellipsoid, whose support along n is below.
    const double rp = prunedRadius(r);
    const double sphere = rp * std::sqrt(cov.m[0][0] + cov.m[1][1] + cov.m[2][2]);
    for (int a = 0; a < 3; ++a) {
        const Vec3d n(slabs.axis[a][0], slabs.axis[a][1], slabs.axis[a][2]);
        double off = 0, reach = 0;
        for (int b = 0; b < 3; ++b) {
            off += n[b] * (p.mean[b] - double(slabs.centre[b]));
            reach += std::fabs(p.mean[b] - double(slabs.centre[b]));
        }
        const double need = std::fabs(off) + support(cov, n, rp) + kCoverageRounding * (sphere + reach);
        if (!(need <= double(slabs.half[a]))) return false;
    }
    return true;
}

GaussianParams<double> gaussianParamsOf(const GaussianCloud& c, std::size_t i)
{
    GaussianParams<double> p;
    p.mean = Vec3d(c.mean(i));
    p.rotation = Quatd{c.rotations[4 * i], c.rotations[4 * i + 1], c.rotations[4 * i + 2], c.rotations[4 * i + 3]};
    p.logScale = Vec3d(c.logScales[3 * i], c.logScales[3 * i + 1], c.logScales[3 * i + 2]);
    p.logit = c.opacities[i];
    return p;
}

void validateStageTwo(const GaussianCloud& cloud, const SampleSet& s, const std::vector<std::uint8_t>& moving,
                      const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& o)
{
    cloud.checkConsistent();
    const std::size_t m = s.sampleCount(), c = s.cellCount();
    if (s.shDegree != cloud.shDegree)
        throw InputError(msg("Stage II: sample SH degree ", s.shDegree, " differs from the model's ", cloud.shDegree));
    if (s.warpedPositions.size() != 3 * m || s.targetF.size() != m * std::size_t(s.featureStride()) ||
        s.sampleCell.size() != m || s.cellGradient.size() != 9 * c)
        throw InputError("Stage II: sample set arrays have inconsistent sizes");
    if (moving.size() != cloud.size() || gaussianCell.size() != cloud.size())
        throw InputError(msg("Stage II: moving/gaussianCell have ", moving.size(), "/", gaussianCell.size(),
                             " entries for ", cloud.size(), " Gaussians"));
    for (std::size_t j = 0; j < m; ++j)
        if (s.sampleCell[j] < 0 || std::size_t(s.sampleCell[j]) >= c)
            throw InputError(msg("Stage II: sample ", j, " has cell ", s.sampleCell[j], " outside 0..", c - 1));
    for (std::size_t i = 0; i < gaussianCell.size(); ++i)
        if (gaussianCell[i] >= std::int32_t(c))
            throw InputError(msg("Stage II: Gaussian ", i, " has cell ", gaussianCell[i], " outside 0..", c - 1));
    if (o.iterations < 0 || o.rebuildEvery < 1 || !(o.cutoff > 0.0f) || o.lambdaLpf < 0.0f)
        throw InputError("Stage II: iterations must be >= 0, rebuildEvery >= 1, cutoff > 0, lambdaLpf >= 0");
}

StageTwoSetup setupStageTwo(const GaussianCloud& cloud, const SampleSet& samples,
                            const std::vector<std::uint8_t>& moving, const std::vector<std::int32_t>& gaussianCell,
                            const StageTwoOptions& options)
{
    validateStageTwo(cloud, samples, moving, gaussianCell, options);
    StageTwoSetup st;
    const bool threaded = options.threaded;
    const int stride = cloud.shStride();
    const float cutoff = options.cutoff;
    auto forEach = [threaded](std::size_t n, std::size_t grain, const auto& op) {
        const tbb::blocked_range<std::size_t> all(0, n, grain);
        auto body = [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) op(i);
        };
        threaded ? tbb::parallel_for(all, body) : body(all);
    };

    // Samples used: those whose cell is not skipped.
    for (std::size_t j = 0; j < samples.sampleCount(); ++j)
        if (!samples.cellSkip[std::size_t(samples.sampleCell[j])]) st.used.push_back(std::uint32_t(j));
    const std::size_t s = st.used.size();
    st.x.resize(3 * s);
    for (std::size_t k = 0; k < s; ++k)
        for (int a = 0; a < 3; ++a)
            st.x[3 * k + std::size_t(a)] = samples.warpedPositions[3 * st.used[k] + std::size_t(a)];
    if (s > 0) {
        Vec3f lo(st.x[0], st.x[1], st.x[2]), hi = lo;
        for (std::size_t k = 0; k < s; ++k)
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], st.x[3 * k + std::size_t(a)]);
                hi[a] = std::max(hi[a], st.x[3 * k + std::size_t(a)]);
            }
        st.sceneExtent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    }

    // Per-Gaussian filters (fixed: F_k of the rest cell does not change during Stage II).
    const std::size_t n = cloud.size();
    st.filter.assign(n, Mat3d());
    if (options.lowPassFilter)
        forEach(n, 1024, [&](std::size_t i) {
            if (gaussianCell[i] >= 0)
                st.filter[i] = lowPassFilter(samples.cellGradient.data() + 9 * std::size_t(gaussianCell[i]),
                                             double(options.lambdaLpf), double(samples.spacing));
        });
    for (std::size_t i = 0; i < n; ++i)
        if (moving[i]) st.moving.push_back(std::uint32_t(i));

    // The static Gaussians' contribution never changes: evaluate it once.
    st.fStatic.assign(s * std::size_t(stride), 0.0f);
    st.oStatic.assign(s, 0.0f);
    std::vector<PreparedGaussian> prepared(n);
    forEach(n, 1024, [&](std::size_t i) {
        if (moving[i]) return; // left out of the bins (empty box)
        prepared[i] = PreparedGaussian::from(prepareParams(gaussianParamsOf(cloud, i), st.filter[i], double(cutoff)));
    });
    GaussianBins bins;
    binPreparedGaussians(prepared, 0.0f, threaded, bins);
    evaluatePreparedFeatures(prepared, cloud.sh.data(), stride, bins, st.x.data(), s, cutoff, threaded,
                             st.fStatic.data(), st.oStatic.data());
    return st;
}

float stageTwoPositionRate(const StageTwoOptions& o, int iteration, float sceneExtent)
{
    const double tFrac = o.iterations > 1 ? double(iteration) / double(o.iterations - 1) : 0.0;
    return float(double(o.lrPositionStart) *
                 std::pow(double(o.lrPositionEnd) / double(o.lrPositionStart), std::min(tFrac, 1.0)) *
                 double(sceneExtent));
}

} // namespace splatwarp
