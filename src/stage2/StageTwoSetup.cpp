#include "stage2/StageTwoSetup.h"

#include <algorithm>
#include <cmath>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "field/FeatureField.h"

namespace splatwarp {

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
        s.sampleCell.size() != m || s.cellGradient.size() != 9 * c ||
        (!s.uniform() && (s.cellAxis.size() != c || s.cellFirst.size() != c + 1)))
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
    if (o.iterations < 0 || o.coverageSteps < 1 || o.rebuildEvery < 0 || !(o.cutoff > 0.0f) || o.lambdaLpf < 0.0f)
        throw InputError("Stage II: iterations must be >= 0, coverageSteps >= 1, rebuildEvery >= 0, cutoff > 0, lambdaLpf >= 0");
}

namespace {

/// The samples whose cell is not skipped, their warped positions and the largest edge of their box.
void selectUsedSamples(const SampleSet& samples, StageTwoSetup& st)
{
    for (std::size_t j = 0; j < samples.sampleCount(); ++j)
        if (!samples.cellSkip[std::size_t(samples.sampleCell[j])]) st.used.push_back(std::uint32_t(j));
    const std::size_t s = st.used.size();
    st.x.resize(3 * s);
    for (std::size_t k = 0; k < s; ++k)
        for (int a = 0; a < 3; ++a)
            st.x[3 * k + std::size_t(a)] = samples.warpedPositions[3 * st.used[k] + std::size_t(a)];
    if (s == 0) return;
    Vec3f lo(st.x[0], st.x[1], st.x[2]), hi = lo;
    for (std::size_t k = 0; k < s; ++k)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], st.x[3 * k + std::size_t(a)]);
            hi[a] = std::max(hi[a], st.x[3 * k + std::size_t(a)]);
        }
    st.sceneExtent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
}

/// Per-Gaussian low-pass filters lambda s_c^2 F_c F_c^T, c the Gaussian's rest cell and s_c its
/// sample spacing (finer in a fine cell, as the rest targets' filter); fixed during Stage II.
std::vector<Mat3d> lowPassFilters(const SampleSet& samples, const std::vector<std::int32_t>& gaussianCell,
                                  const StageTwoOptions& options)
{
    std::vector<Mat3d> filter(gaussianCell.size(), Mat3d());
    if (options.lowPassFilter)
        parallelFor(filter.size(), 1024, options.threaded, [&](std::size_t i) {
            if (gaussianCell[i] >= 0)
                filter[i] = lowPassFilter(samples.cellGradient.data() + 9 * std::size_t(gaussianCell[i]),
                                          double(options.lambdaLpf),
                                          double(samples.spacingOf(std::size_t(gaussianCell[i]))));
        });
    return filter;
}

/// The static Gaussians' contribution to F and O at the used samples (it never changes: evaluated once).
void evaluateStaticContribution(const GaussianCloud& cloud, const std::vector<std::uint8_t>& moving,
                                const StageTwoOptions& options, StageTwoSetup& st)
{
    const std::size_t s = st.used.size(), n = cloud.size();
    const int stride = cloud.shStride();
    st.fStatic.assign(s * std::size_t(stride), 0.0f);
    st.oStatic.assign(s, 0.0f);
    std::vector<PreparedGaussian> prepared(n);
    parallelFor(n, 1024, options.threaded, [&](std::size_t i) {
        if (moving[i]) return; // left out of the bins (empty box)
        prepared[i] =
            PreparedGaussian::from(prepareParams(gaussianParamsOf(cloud, i), st.filter[i], double(options.cutoff)));
    });
    GaussianBins bins;
    binPreparedGaussians(prepared, 0.0f, options.threaded, bins);
    evaluatePreparedFeatures(prepared, cloud.sh.data(), stride, bins, st.x.data(), s, options.cutoff, options.threaded,
                             st.fStatic.data(), st.oStatic.data());
}

} // namespace

StageTwoSetup setupStageTwo(const GaussianCloud& cloud, const SampleSet& samples,
                            const std::vector<std::uint8_t>& moving, const std::vector<std::int32_t>& gaussianCell,
                            const StageTwoOptions& options, bool staticContribution)
{
    validateStageTwo(cloud, samples, moving, gaussianCell, options);
    StageTwoSetup st;
    selectUsedSamples(samples, st);
    st.filter = lowPassFilters(samples, gaussianCell, options);
    for (std::size_t i = 0; i < cloud.size(); ++i)
        if (moving[i]) st.moving.push_back(std::uint32_t(i));
    if (staticContribution) evaluateStaticContribution(cloud, moving, options, st);
    return st;
}

} // namespace splatwarp
