#include "stage2/StageTwo.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>
#include <cmath>

#include "core/Error.h"
#include "core/Progress.h"
#include "field/FeatureField.h"
#include "stage2/Adam.h"
#include "stage2/Coverage.h"
#include "stage2/PairGradients.h"
#include "stage2/StageTwoCommon.h"

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

} // namespace

StageTwoReport optimiseStageTwo(GaussianCloud& cloud, const SampleSet& samples, const std::vector<std::uint8_t>& moving,
                                const std::vector<std::int32_t>& gaussianCell, const StageTwoOptions& options,
                                const std::function<void(int, const GaussianCloud&)>& onEval, int evalEvery)
{
    Stopwatch total, phase;
    StageTwoReport report;
    const StageTwoSetup setup = setupStageTwo(cloud, samples, moving, gaussianCell, options);
    const bool threaded = options.threaded;
    const int stride = cloud.shStride();
    const float cutoff = options.cutoff;
    const std::vector<std::uint32_t>& used = setup.used;
    const std::vector<float>& x = setup.x;
    const std::vector<std::uint32_t>& mov = setup.moving;
    const std::vector<Mat3d>& filter = setup.filter;
    const std::vector<float>& fStatic = setup.fStatic;
    const std::vector<float>& oStatic = setup.oStatic;
    const std::size_t s = used.size(), g = mov.size();
    report.samplesUsed = s;
    report.samplesSkipped = samples.sampleCount() - s;
    report.sceneExtent = setup.sceneExtent;
    report.movingGaussians = g;
    report.msSetup = phase.ms();

    std::vector<PreparedGaussian> kernels(g);
    std::vector<float> boxLo(3 * g), boxHi(3 * g);
    std::vector<CoverageSlabs> slabs(g);
    std::vector<std::uint8_t> holds(g);
    std::vector<float> gF(s * std::size_t(stride)), gO(s), energy(3 * s);
    std::vector<std::uint32_t> pairCount(s);
    // Parameter layout per moving Gaussian: mean 3, rotation 4, logScale 3, logit 1, SH stride.
    const std::size_t perG = 11 + std::size_t(stride);
    std::vector<float> grad(g * perG);
    Adam adam(g * perG, options.beta1, options.beta2, options.epsilon);
    Coverage coverage;
    const double lambda1 = options.lambdaOpacity, lambda2 = options.boundaryWeight;

    auto positionRate = [&](int iteration) { return stageTwoPositionRate(options, iteration, report.sceneExtent); };
    auto prepareKernels = [&] {
        forEach(g, 256, threaded, [&](std::size_t k) {
            const std::size_t i = mov[k];
            kernels[k] = PreparedGaussian::from(prepareParams(gaussianParamsOf(cloud, i), filter[i], double(cutoff)));
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
            const GaussianParams<double> p = gaussianParamsOf(cloud, i);
            stageTwoCoverageBox(p, filter[i], steps, move, options, &boxLo[3 * k], &boxHi[3 * k]);
            stageTwoCoverageSlabs(p, filter[i], steps, move, options, slabs[k]);
        });
        coverage.build(boxLo.data(), boxHi.data(), g, x.data(), s, threaded, slabs.data());
        report.coveragePairs = coverage.pairCount();
        ++report.coverageRebuilds;
        report.msCoverage += sw.ms();
    };
    // The learning-rate bound behind the boxes is an estimate (Adam can step further): check
    // each Gaussian is still inside its box and slabs, so a missed pair forces a rebuild
    // instead of silently changing the result.
    auto coverageHolds = [&] {
        forEach(g, 256, threaded, [&](std::size_t k) {
            const std::size_t i = mov[k];
            holds[k] = stageTwoCoverageHolds(gaussianParamsOf(cloud, i), filter[i], double(cutoff), &boxLo[3 * k],
                                             &boxHi[3 * k], slabs[k]);
        });
        return std::all_of(holds.begin(), holds.end(), [](std::uint8_t h) { return h != 0; });
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
            const GaussianParamGrad<double> pg = paramBackward(gaussianParamsOf(cloud, i), acc);
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

    // The moving Gaussians' parameters of the best iterate so far (keepBest), packed per Gaussian
    // as means, rotation, log-scales, logit, SH.
    const std::size_t packed = std::size_t(11 + stride);
    std::vector<float> best(options.keepBest ? g * packed : 0);
    auto snapshot = [&](bool save) {
        forEach(g, 1024, threaded, [&](std::size_t k) {
            const std::size_t i = mov[k];
            float* b = best.data() + k * packed;
            float* fields[5] = {&cloud.means[3 * i], &cloud.rotations[4 * i], &cloud.logScales[3 * i], &cloud.opacities[i],
                                cloud.shOf(i)};
            const int sizes[5] = {3, 4, 3, 1, stride};
            for (int f = 0; f < 5; ++f) {
                if (save) std::copy(fields[f], fields[f] + sizes[f], b);
                else std::copy(b, b + sizes[f], fields[f]);
                b += sizes[f];
            }
        });
    };
    report.bestEnergy = std::numeric_limits<double>::infinity();

    const int reportEvery = std::max(options.reportEvery, 1);
    for (int it = 0; it <= options.iterations; ++it) {
        prepareKernels();
        const bool scheduled = (it < options.iterations && it % options.rebuildEvery == 0) || it == 0;
        if (scheduled) rebuildCoverage(it);
        else if (!coverageHolds()) {
            rebuildCoverage(it);
            ++report.coverageForcedRebuilds;
        }
        const auto [e, pairs] = forward(it);
        if (!options.keepBest || e.total < report.bestEnergy) {
            report.bestEnergy = e.total;
            report.bestIteration = it;
            if (options.keepBest && it < options.iterations) snapshot(true);
        }
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
    if (options.keepBest && report.bestIteration != options.iterations) {
        snapshot(false);
        progress(msg("Stage II: kept iteration ", report.bestIteration, " (lowest energy ", report.bestEnergy, ")"));
    }
    report.msTotal = total.ms();
    return report;
}

} // namespace splatwarp
