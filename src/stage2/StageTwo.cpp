#include "stage2/StageTwo.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "core/Error.h"
#include "core/Progress.h"
#include "field/FeatureField.h"
#include "stage2/Adam.h"
#include "stage2/Coverage.h"
#include "stage2/PairGradients.h"

namespace splatwarp {
namespace {

template <typename Op>
void forEach(std::size_t n, std::size_t grain, bool threaded, const Op& op)
{
    const tbb::blocked_range<std::size_t> all(0, n, grain);
    auto body = [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) op(i);
    };
    threaded ? tbb::parallel_for(all, body) : body(all);
}

GaussianParams<double> paramsOf(const GaussianCloud& c, std::size_t i)
{
    GaussianParams<double> p;
    p.mean = Vec3d(c.mean(i));
    p.rotation = Quatd{c.rotations[4 * i], c.rotations[4 * i + 1], c.rotations[4 * i + 2], c.rotations[4 * i + 3]};
    p.logScale = Vec3d(c.logScales[3 * i], c.logScales[3 * i + 1], c.logScales[3 * i + 2]);
    p.logit = c.opacities[i];
    return p;
}

void validate(const GaussianCloud& cloud, const SampleSet& s, const std::vector<std::uint8_t>& moving,
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

} // namespace

StageTwoReport optimiseStageTwo(GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                                const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options,
                                const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery)
{
    Stopwatch total, phase;
    validate(cloud, samples, moving, gaussianCell, options);
    StageTwoReport report;
    const bool threaded = options.threaded;
    const int stride = cloud.shStride();
    const float cutoff = options.cutoff;

    // Samples used: those whose cell is not skipped.
    std::vector<std::uint32_t> used;
    for (std::size_t j = 0; j < samples.sampleCount(); ++j)
        if (!samples.cellSkip[std::size_t(samples.sampleCell[j])]) used.push_back(std::uint32_t(j));
    const std::size_t s = used.size();
    report.samplesUsed = s;
    report.samplesSkipped = samples.sampleCount() - s;
    std::vector<float> x(3 * s);
    for (std::size_t k = 0; k < s; ++k)
        for (int a = 0; a < 3; ++a) x[3 * k + std::size_t(a)] = samples.warpedPositions[3 * used[k] + std::size_t(a)];
    if (s > 0) {
        Vec3f lo(x[0], x[1], x[2]), hi = lo;
        for (std::size_t k = 0; k < s; ++k)
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], x[3 * k + std::size_t(a)]);
                hi[a] = std::max(hi[a], x[3 * k + std::size_t(a)]);
            }
        report.sceneExtent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    }

    // Per-Gaussian filters (fixed: F_k of the rest cell does not change during Stage II).
    const std::size_t n = cloud.size();
    std::vector<Mat3d> filter(n);
    if (options.lowPassFilter)
        forEach(n, 1024, threaded, [&](std::size_t i) {
            if (gaussianCell[i] >= 0)
                filter[i] = lowPassFilter(samples.cellGradient.data() + 9 * std::size_t(gaussianCell[i]),
                                          double(options.lambdaLpf), double(samples.spacing));
        });

    std::vector<std::uint32_t> mov;
    for (std::size_t i = 0; i < n; ++i)
        if (moving[i]) mov.push_back(std::uint32_t(i));
    const std::size_t g = mov.size();
    report.movingGaussians = g;

    // The static Gaussians' contribution never changes: evaluate it once.
    std::vector<float> fStatic(s * std::size_t(stride), 0.0f), oStatic(s, 0.0f);
    {
        std::vector<PreparedGaussian> prepared(n);
        forEach(n, 1024, threaded, [&](std::size_t i) {
            if (moving[i]) return; // left out of the bins (empty box)
            const GaussianParams<double> p = paramsOf(cloud, i);
            prepared[i] = PreparedGaussian::from(prepareParams(p, filter[i], double(cutoff)));
        });
        GaussianBins bins;
        binPreparedGaussians(prepared, 0.0f, threaded, bins);
        evaluatePreparedFeatures(prepared, cloud.sh.data(), stride, bins, x.data(), s, cutoff, threaded,
                                 fStatic.data(), oStatic.data());
    }
    report.msSetup = phase.ms();

    std::vector<PreparedGaussian> kernels(g);
    std::vector<float> boxLo(3 * g), boxHi(3 * g);
    std::vector<float> gF(s * std::size_t(stride)), gO(s), energy(3 * s);
    std::vector<std::uint32_t> pairCount(s);
    // Parameter layout per moving Gaussian: mean 3, rotation 4, logScale 3, logit 1, SH stride.
    const std::size_t perG = 11 + std::size_t(stride);
    std::vector<float> grad(g * perG);
    Adam adam(g * perG, options.beta1, options.beta2, options.epsilon);
    Coverage coverage;
    const double lambda1 = options.lambdaOpacity, lambda2 = options.boundaryWeight;

    // Position learning rate: exponential from start to end over the run, times the scene extent.
    auto positionRate = [&](int iteration) {
        const double tFrac = options.iterations > 1 ? double(iteration) / double(options.iterations - 1) : 0.0;
        return float(double(options.lrPositionStart) *
                     std::pow(double(options.lrPositionEnd) / double(options.lrPositionStart), std::min(tFrac, 1.0)) *
                     double(report.sceneExtent));
    };
    auto prepareKernels = [&] {
        forEach(g, 256, threaded, [&](std::size_t k) {
            const std::size_t i = mov[k];
            kernels[k] = PreparedGaussian::from(prepareParams(paramsOf(cloud, i), filter[i], double(cutoff)));
        });
    };
    auto rebuildCoverage = [&](int iteration) {
        Stopwatch sw;
        // Grow each box by what `steps` Adam steps can do (each step moves a parameter by about
        // its learning rate): opacity and scale grow the ellipsoid, rotation turns it, the mean
        // moves. Then a relative margin on top.
        const int steps = std::max(1, std::min(options.rebuildEvery, options.iterations - iteration));
        const double move = double(steps) * double(positionRate(iteration)); // per axis
        forEach(g, 256, threaded, [&](std::size_t k) {
            const std::size_t i = mov[k];
            GaussianParams<double> p = paramsOf(cloud, i);
            const double qn = std::sqrt(p.rotation.w * p.rotation.w + p.rotation.x * p.rotation.x +
                                        p.rotation.y * p.rotation.y + p.rotation.z * p.rotation.z);
            const double angle = std::min(4.0 * double(steps) * double(options.lrRotation) / std::max(qn, 1e-12), M_PI);
            p.logit += double(steps) * double(options.lrOpacity);
            for (int a = 0; a < 3; ++a) p.logScale[a] += double(steps) * double(options.lrLogScale);
            const Vec3d sc(std::exp(p.logScale.x), std::exp(p.logScale.y), std::exp(p.logScale.z));
            const Mat3d cov = filteredCovariance(p.rotation, sc, filter[i]);
            const double r = extentRadius(sigmoid(p.logit), double(cutoff));
            const Vec3d half = ellipsoidHalfExtent(cov, r);
            const double sphere = r * std::sqrt(cov.m[0][0] + cov.m[1][1] + cov.m[2][2]);
            for (int a = 0; a < 3; ++a) {
                const double h = r > 0 ? std::min(sphere, half[a] * (1.0 + double(options.coveragePad)) + sphere * angle) + move
                                       : -1.0;
                boxLo[3 * k + std::size_t(a)] = float(p.mean[a] - h);
                boxHi[3 * k + std::size_t(a)] = float(p.mean[a] + h);
            }
        });
        coverage.build(boxLo.data(), boxHi.data(), g, x.data(), s, threaded);
        report.coveragePairs = coverage.pairCount();
        ++report.coverageRebuilds;
        report.msCoverage += sw.ms();
    };
    // Forward: F, O per sample, the loss and its gradient; returns the energy terms.
    auto forward = [&](int iteration) {
        Stopwatch sw;
        const auto& so = coverage.sampleOffsets();
        const auto& si = coverage.sampleItems();
        forEach(s, 256, threaded, [&](std::size_t j) {
            float f[48];
            const float* fs = fStatic.data() + j * std::size_t(stride);
            std::copy(fs, fs + stride, f);
            float o = oStatic[j];
            const Vec3f xj(x[3 * j], x[3 * j + 1], x[3 * j + 2]);
            std::uint32_t counted = 0;
            for (std::uint32_t e = so[j]; e < so[j + 1]; ++e) {
                const std::uint32_t k = si[e];
                const float w = kernels[k].weight(xj - kernels[k].mean, cutoff);
                if (w == 0.0f) continue;
                ++counted;
                o += w;
                const float* h = cloud.shOf(mov[k]);
                for (int c = 0; c < stride; ++c) f[c] += w * h[c];
            }
            pairCount[j] = counted;
            const std::size_t sj = used[j];
            float terms[3];
            sampleLoss<float, float>(f, samples.targetF.data() + sj * std::size_t(stride), o, samples.targetO[sj],
                                     stride, float(lambda1), float(lambda2), gF.data() + j * std::size_t(stride),
                                     gO[j], terms);
            for (int t = 0; t < 3; ++t) energy[3 * j + std::size_t(t)] = terms[t];
        });
        // Serial sums in sample order: deterministic for any thread count.
        StageTwoEnergy e;
        e.iteration = iteration;
        std::uint64_t pairs = 0;
        for (std::size_t j = 0; j < s; ++j) {
            e.color += energy[3 * j];
            e.opacity += energy[3 * j + 1];
            e.boundary += energy[3 * j + 2];
            pairs += pairCount[j];
        }
        e.total = e.color + e.opacity + e.boundary;
        report.msForward += sw.ms();
        return std::make_pair(e, pairs);
    };
    auto backward = [&] {
        Stopwatch sw;
        const auto& go = coverage.gaussianOffsets();
        const auto& gi = coverage.gaussianItems();
        forEach(g, 16, threaded, [&](std::size_t k) {
            const std::size_t i = mov[k];
            const PreparedGaussian& kg = kernels[k];
            const float* h = cloud.shOf(i);
            GaussianAccum<double> acc;
            double gh[48] = {0};
            for (std::uint32_t e = go[k]; e < go[k + 1]; ++e) {
                const std::uint32_t j = gi[e];
                const Vec3f xj(x[3 * j], x[3 * j + 1], x[3 * j + 2]);
                Vec3f ad;
                const float w = kg.weight(xj - kg.mean, cutoff, &ad);
                if (w == 0.0f) continue;
                const float* gfj = gF.data() + std::size_t(j) * std::size_t(stride);
                double gw = gO[j];
                for (int c = 0; c < stride; ++c) {
                    gw += double(gfj[c]) * double(h[c]);
                    gh[c] += double(w) * double(gfj[c]);
                }
                pairBackward<double>(gw, double(w), double(kg.alpha), Vec3d(ad), acc);
            }
            const GaussianParamGrad<double> pg = paramBackward(paramsOf(cloud, i), acc);
            float* out = grad.data() + k * perG;
            for (int a = 0; a < 3; ++a) out[a] = float(pg.mean[a]);
            out[3] = float(pg.rotation.w); out[4] = float(pg.rotation.x);
            out[5] = float(pg.rotation.y); out[6] = float(pg.rotation.z);
            for (int a = 0; a < 3; ++a) out[7 + a] = float(pg.logScale[a]);
            out[10] = float(pg.logit);
            for (int c = 0; c < stride; ++c) out[11 + c] = float(gh[c]);
        });
        report.msBackward += sw.ms();
    };
    auto step = [&](int iteration) {
        Stopwatch sw;
        const float lrPos = positionRate(iteration);
        adam.beginStep(iteration + 1);
        forEach(g, 1024, threaded, [&](std::size_t k) {
            const std::size_t i = mov[k];
            const float* gk = grad.data() + k * perG;
            const std::size_t base = k * perG;
            for (int a = 0; a < 3; ++a) adam.update(base + std::size_t(a), cloud.means[3 * i + std::size_t(a)], gk[a], lrPos);
            for (int a = 0; a < 4; ++a)
                adam.update(base + 3 + std::size_t(a), cloud.rotations[4 * i + std::size_t(a)], gk[3 + a], options.lrRotation);
            for (int a = 0; a < 3; ++a)
                adam.update(base + 7 + std::size_t(a), cloud.logScales[3 * i + std::size_t(a)], gk[7 + a], options.lrLogScale);
            adam.update(base + 10, cloud.opacities[i], gk[10], options.lrOpacity);
            float* h = cloud.shOf(i);
            for (int c = 0; c < stride; ++c) adam.update(base + 11 + std::size_t(c), h[c], gk[11 + c], options.lrSh);
        });
        report.msUpdate += sw.ms();
    };

    const int reportEvery = std::max(options.reportEvery, 1);
    for (int it = 0; it <= options.iterations; ++it) {
        prepareKernels();
        if (it < options.iterations && it % options.rebuildEvery == 0) rebuildCoverage(it);
        if (it == 0 && options.iterations == 0) rebuildCoverage(it);
        const auto [e, pairs] = forward(it);
        if (it % reportEvery == 0 || it == options.iterations) {
            report.energies.push_back(e);
            progress(msg("Stage II iteration ", it, ": energy ", e.total, " (colour ", e.color, ", opacity ",
                         e.opacity, ", boundary ", e.boundary, "), ", pairs, " pairs"));
        }
        if (it == options.iterations) break; // final energy only
        report.pairsPerIteration.push_back(pairs);
        backward();
        step(it);
        if (onEval && evalEvery > 0 && (it + 1) % evalEvery == 0) onEval(it + 1, cloud);
    }
    report.msTotal = total.ms();
    return report;
}

} // namespace splatwarp
