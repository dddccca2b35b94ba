#include "train/Trainer.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "core/Progress.h"
#include "image/Metrics.h"
#include "render/RasterizerBackward.h"
#include "train/ImageLoss.h"

namespace splatwarp {

namespace {

// Adam as 3DGS configures PyTorch's: betas (0.9, 0.999), eps 1e-15, bias-corrected.
constexpr double kBeta1 = 0.9, kBeta2 = 0.999, kAdamEps = 1e-15;

/// First and second moments with the model's layout, so densification edits all three alike.
struct AdamState {
    GaussianCloud m1, m2;
    int step = 0;
};

/// Per-Gaussian statistics gathered between densifications.
struct DensifyStats {
    std::vector<double> gradSum;
    std::vector<int> views;
    std::vector<float> maxRadius;
    void reset(std::size_t n)
    {
        gradSum.assign(n, 0.0);
        views.assign(n, 0);
        maxRadius.assign(n, 0.0f);
    }
};

/// One Adam step of an array; element i uses lrFirst when i % stride < first (SH band 0), else lr.
void adamArray(std::vector<float>& p, const std::vector<float>& g, std::vector<float>& m, std::vector<float>& v,
               double lr, int step, bool threaded, std::size_t stride = 1, std::size_t first = 1, double lrFirst = -1)
{
    const float c1 = float(1.0 - std::pow(kBeta1, step)), c2 = float(1.0 - std::pow(kBeta2, step));
    const float b1 = float(kBeta1), b2 = float(kBeta2);
    const float rate = float(lr), rateFirst = float(lrFirst < 0 ? lr : lrFirst);
    parallelForRange(p.size(), 16384, threaded, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) {
            m[i] = b1 * m[i] + (1 - b1) * g[i];
            v[i] = b2 * v[i] + (1 - b2) * g[i] * g[i];
            const float r = i % stride < first ? rateFirst : rate;
            p[i] -= r * (m[i] / c1) / (std::sqrt(v[i] / c2) + float(kAdamEps));
        }
    });
}

void adamStep(GaussianCloud& c, const CloudGradients& g, AdamState& s, const TrainOptions& o, double positionLr)
{
    ++s.step;
    adamArray(c.means, g.means, s.m1.means, s.m2.means, positionLr, s.step, o.threaded);
    adamArray(c.logScales, g.logScales, s.m1.logScales, s.m2.logScales, o.scalingLr, s.step, o.threaded);
    adamArray(c.rotations, g.rotations, s.m1.rotations, s.m2.rotations, o.rotationLr, s.step, o.threaded);
    adamArray(c.opacities, g.opacities, s.m1.opacities, s.m2.opacities, o.opacityLr, s.step, o.threaded);
    adamArray(c.sh, g.sh, s.m1.sh, s.m2.sh, o.featureRestLr, s.step, o.threaded, std::size_t(c.shStride()), 3, o.featureLr);
}

/// A copy of Gaussian i of `from` appended to `to`, and zero moments for it.
void appendWithZeroMoments(GaussianCloud& to, AdamState& next, const GaussianCloud& from, std::size_t i, const GaussianCloud& zero)
{
    to.append(from, i);
    next.m1.append(zero, 0);
    next.m2.append(zero, 0);
}

/// Clone small Gaussians and split large ones whose mean view-space gradient is high, prune the
/// transparent (and, after the first opacity reset, the huge) ones. Moments follow their Gaussian.
void densifyAndPrune(GaussianCloud& c, AdamState& s, const DensifyStats& st, const TrainOptions& o, double extent,
                     bool pruneBig, std::mt19937& rng)
{
    GaussianCloud out, zero;
    out.resize(0, c.shDegree);
    zero.resize(1, c.shDegree);
    std::fill(zero.rotations.begin(), zero.rotations.end(), 0.0f);
    AdamState next;
    next.step = s.step;
    next.m1.resize(0, c.shDegree);
    next.m2.resize(0, c.shDegree);
    std::normal_distribution<float> normal(0.0f, 1.0f);
    bool room = c.size() < o.maxGaussians;
    for (std::size_t i = 0; i < c.size(); ++i) {
        const Vec3f sc = c.scale(i);
        const float largest = std::max({sc.x, sc.y, sc.z});
        const bool prune = c.alpha(i) < o.pruneOpacity ||
                           (pruneBig && (st.maxRadius[i] > o.maxScreenRadius || largest > 0.1 * extent));
        if (prune) continue;
        const bool hot = room && st.views[i] > 0 && st.gradSum[i] / st.views[i] >= o.densifyGradThreshold;
        if (hot && largest > o.percentDense * extent) {
            // Split: two samples of the Gaussian, each 1.6x smaller.
            const Mat3f r = quatToMatrix(c.rotation(i));
            for (int k = 0; k < 2; ++k) {
                const Vec3f local(normal(rng) * sc.x, normal(rng) * sc.y, normal(rng) * sc.z);
                appendWithZeroMoments(out, next, c, i, zero);
                const std::size_t j = out.size() - 1;
                out.setMean(j, c.mean(i) + r * local);
                for (int a = 0; a < 3; ++a) out.logScales[3 * j + std::size_t(a)] = c.logScales[3 * i + std::size_t(a)] - std::log(1.6f);
            }
            continue;
        }
        out.append(c, i);
        next.m1.append(s.m1, i);
        next.m2.append(s.m2, i);
        if (hot) appendWithZeroMoments(out, next, c, i, zero); // clone: a second copy in place
        room = room && out.size() < o.maxGaussians;
    }
    c = std::move(out);
    s = std::move(next);
}

void resetOpacities(GaussianCloud& c, AdamState& s)
{
    const float cap = std::log(0.01f / 0.99f); // logit of 0.01
    for (std::size_t i = 0; i < c.size(); ++i) {
        c.opacities[i] = std::min(c.opacities[i], cap);
        s.m1.opacities[i] = s.m2.opacities[i] = 0.0f;
    }
}

void checkViews(const std::vector<TrainingView>& views)
{
    if (views.empty()) throw InputError("training needs at least one view");
    for (const TrainingView& v : views)
        if (v.image.width != v.camera.width || v.image.height != v.camera.height || v.image.channels < 3)
            throw InputError(msg("view '", v.camera.name, "': a ", v.image.width, "x", v.image.height, " picture for a ",
                                 v.camera.width, "x", v.camera.height, " camera"));
}

} // namespace

TrainOptions compressedSchedule(int iterations)
{
    TrainOptions o;
    const double f = double(iterations) / o.iterations;
    const auto scaled = [f](int steps) { return std::max(1, int(std::lround(steps * f))); };
    o.iterations = iterations;
    o.shInterval = scaled(o.shInterval);
    o.densifyFrom = scaled(o.densifyFrom);
    o.densifyUntil = scaled(o.densifyUntil);
    // At least 25 views between densifications: fewer make the mean gradient too noisy to judge by.
    o.densifyInterval = std::max(25, scaled(o.densifyInterval));
    o.opacityResetInterval = scaled(o.opacityResetInterval);
    return o;
}

double cameraExtent(const std::vector<TrainingView>& views)
{
    Vec3d mean;
    for (const TrainingView& v : views) mean += v.camera.centre() / double(views.size());
    double r = 0;
    for (const TrainingView& v : views) r = std::max(r, length(v.camera.centre() - mean));
    return 1.1 * (r > 0 ? r : 1.0);
}

ViewScores scoreViews(const GaussianCloud& cloud, const std::vector<TrainingView>& views, const Vec3f& background, bool threaded)
{
    ViewScores s;
    RenderOptions ro;
    ro.background = background;
    ro.threaded = threaded;
    for (const TrainingView& v : views) {
        const Image r = renderGaussians(cloud, v.camera, ro);
        s.names.push_back(v.camera.name);
        s.psnr.push_back(psnr(r, v.image));
        s.ssim.push_back(ssim(r, v.image));
        s.meanPsnr += s.psnr.back() / double(views.size());
        s.meanSsim += s.ssim.back() / double(views.size());
    }
    return s;
}

GaussianCloud randomGaussians(const Vec3d& lo, const Vec3d& hi, std::size_t count, unsigned seed)
{
    GaussianCloud g;
    g.resize(count, 0);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const Vec3d e = hi - lo;
    const double spacing = std::cbrt(std::max(e.x * e.y * e.z, 1e-30) / double(std::max<std::size_t>(count, 1)));
    for (std::size_t i = 0; i < count; ++i) {
        g.setMean(i, Vec3f(lo + Vec3d(e.x * u(rng), e.y * u(rng), e.z * u(rng))));
        for (int a = 0; a < 3; ++a) g.logScales[3 * i + std::size_t(a)] = float(std::log(spacing));
        g.opacities[i] = std::log(0.1f / 0.9f);
    }
    return g;
}

namespace {

/// The model at options.shDegree with its higher bands zero (they are trained once unlocked).
GaussianCloud raisedDegree(const GaussianCloud& init, int degree)
{
    if (init.shDegree >= degree) return init;
    GaussianCloud c;
    c.resize(init.size(), degree);
    c.means = init.means;
    c.rotations = init.rotations;
    c.logScales = init.logScales;
    c.opacities = init.opacities;
    for (std::size_t i = 0; i < init.size(); ++i) std::copy_n(init.shOf(i), init.shStride(), c.shOf(i));
    return c;
}

/// One optimisation step on one view; returns the loss.
double trainStep(GaussianCloud& c, AdamState& adam, DensifyStats& st, CloudGradients& g, const TrainingView& view,
                 const TrainOptions& o, int activeDegree, double positionLr)
{
    RenderOptions ro;
    ro.background = o.background;
    ro.threaded = o.threaded;
    const RenderTape tape = renderForTraining(c, view.camera, ro);
    const ImageLossResult loss = imageLoss(tape.image, view.image, o.lambdaDssim, o.threaded);
    g.reset(c);
    renderBackward(c, tape, loss.gradient, g, o.threaded);
    // Bands not yet unlocked stay zero.
    const std::size_t stride = std::size_t(c.shStride()), active = std::size_t(3 * shCoeffCount(activeDegree));
    for (std::size_t j = 0; j < g.sh.size(); ++j)
        if (j % stride >= active) g.sh[j] = 0.0f;
    for (std::size_t i = 0; i < c.size(); ++i) {
        if (g.visible[i] == 0) continue;
        st.gradSum[i] += g.screenNorm[i];
        st.views[i] += 1;
        st.maxRadius[i] = std::max(st.maxRadius[i], tape.bins.splats[i].p.radius);
    }
    adamStep(c, g, adam, o, positionLr);
    return loss.loss;
}

} // namespace

GaussianCloud trainGaussians(const GaussianCloud& init, const std::vector<TrainingView>& views, const TrainOptions& o,
                             TrainReport* report, const std::function<void(const std::string&)>& progress)
{
    checkViews(views);
    if (init.empty()) throw InputError("training needs at least one initial Gaussian");
    if (o.iterations < 0 || o.shDegree < 0 || o.shDegree > 3) throw InputError("invalid training options");
    init.checkConsistent();
    GaussianCloud c = raisedDegree(init, o.shDegree);
    const double extent = cameraExtent(views);
    AdamState adam;
    adam.m1.resize(c.size(), c.shDegree);
    adam.m2.resize(c.size(), c.shDegree);
    std::fill(adam.m1.rotations.begin(), adam.m1.rotations.end(), 0.0f);
    std::fill(adam.m2.rotations.begin(), adam.m2.rotations.end(), 0.0f);
    DensifyStats st;
    st.reset(c.size());
    CloudGradients g;
    std::mt19937 rng(o.seed);
    std::vector<std::size_t> order;
    Stopwatch watch;
    double recent = 0;
    int recentCount = 0;
    for (int it = 1; it <= o.iterations; ++it) {
        if (order.empty()) { // a fresh random pass over the views, as 3DGS
            order.resize(views.size());
            std::iota(order.begin(), order.end(), 0);
            std::shuffle(order.begin(), order.end(), rng);
        }
        const TrainingView& view = views[order.back()];
        order.pop_back();
        const double t = o.iterations > 1 ? double(it - 1) / double(o.iterations - 1) : 1.0;
        const double lr = extent * std::exp((1 - t) * std::log(o.positionLrStart) + t * std::log(o.positionLrEnd));
        const int degree = std::min(o.shDegree, (it - 1) / std::max(1, o.shInterval));
        const double loss = trainStep(c, adam, st, g, view, o, degree, lr);
        if (it > o.iterations - 100) {
            recent += loss;
            ++recentCount;
        }
        if (it < o.densifyUntil) {
            if (it > o.densifyFrom && it % o.densifyInterval == 0) {
                densifyAndPrune(c, adam, st, o, extent, it > o.opacityResetInterval, rng);
                st.reset(c.size());
            }
            if (it % o.opacityResetInterval == 0) resetOpacities(c, adam);
        }
        if (progress && o.progressEvery > 0 && (it % o.progressEvery == 0 || it == o.iterations))
            progress(msg("train: step ", it, "/", o.iterations, "  loss ", loss, "  ", c.size(), " Gaussians  SH ", degree,
                         "  ", int(watch.ms() / 1000), " s"));
    }
    if (report) {
        report->iterations = o.iterations;
        report->gaussians = c.size();
        report->seconds = watch.ms() / 1000.0;
        report->finalLoss = recentCount > 0 ? recent / recentCount : 0.0;
    }
    return c;
}

} // namespace splatwarp
