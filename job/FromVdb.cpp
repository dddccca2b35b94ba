#include "job/FromVdb.h"

#include <algorithm>
#include <cmath>
#include <sys/resource.h>

#include "job/HeldOutEval.h"
#include "core/Error.h"
#include "core/Memory.h"
#include "core/Progress.h"
#include "field/FeatureDevice.h"
#include "fit/Extinction.h"
#include "image/BitmapFont.h"
#include "render/RayMarcher.h"
#include "render/RenderDevice.h"
#include "sh/SphericalHarmonics.h"
#include "stage2/StageTwo.h"

namespace splatwarp {

namespace {

double cpuSeconds()
{
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

void divide(std::vector<float>& v, double s)
{
    if (s != 1.0)
        for (float& x : v) x = float(double(x) / s);
}

/// The fit's low-pass filter: our own files hold the rest-filtered field (variance lambda s^2),
/// so the fit uses the same filter and the Gaussians themselves come out unfiltered.
/// The engine's filter is lambda * spacing^2 with spacing = voxel / perAxis here.
void setFitFilter(const Volume& volume, int perAxis, StageTwoOptions& s2)
{
    s2.lowPassFilter = volume.info().ownFile && volume.info().lambdaLpf > 0;
    if (s2.lowPassFilter) s2.lambdaLpf = volume.info().lambdaLpf * float(perAxis * perAxis);
}

nlohmann::json inputJson(const VolumeInfo& i)
{
    return {{"path", i.path},       {"grid", i.grid},         {"colorGrid", i.colorGrid},
            {"shDegree", i.shDegree}, {"voxelSize", i.voxelSize}, {"activeVoxels", i.activeVoxels},
            {"min", i.minValue},    {"max", i.maxValue},      {"ownFile", i.ownFile},
            {"levelSet", i.levelSet}, {"lambdaLpf", i.lambdaLpf}, {"notes", i.notes}};
}

nlohmann::json fitJson(const VolumeFitReport& r)
{
    nlohmann::json rounds = nlohmann::json::array();
    for (const StageTwoReport& s : r.rounds) {
        rounds.push_back({{"device", deviceName(s.device)},
                          {"iterations", s.pairsPerIteration.size()},
                          {"bestIteration", s.bestIteration},
                          {"rejectedSteps", s.rejectedSteps},
                          {"stoppedAt", s.stoppedAt},
                          {"energyFirst", s.energies.empty() ? 0.0 : s.energies.front().total},
                          {"energyBest", s.bestEnergy},
                          {"samplesUsed", s.samplesUsed},
                          {"pairsPerIteration", s.pairsPerIteration.empty() ? 0 : s.pairsPerIteration.back()},
                          {"coveragePairs", s.coveragePairs},
                          {"coverageRebuilds", s.coverageRebuilds},
                          {"ms", s.msTotal},
                          {"coverageMs", s.msCoverage},
                          {"forwardMs", s.msForward},
                          {"backwardMs", s.msBackward}});
    }
    return {{"rounds", rounds}, {"pruned", r.pruned}, {"split", r.split}, {"splitMs", r.msSplit}};
}

/// Bytes of one training sample: the sample set's and Stage II's own.
std::size_t fitBytesPerSample(int shDegree) { return SampleSet::bytesPerSample(shDegree) + stageTwoBytesPerSample(shDegree); }

/// Refuse samples that would not fit --max-memory beside what the process holds, before building
/// them (the volume's 1 KB per voxel estimate was 1.75x short of a 10.8 M-voxel fit's 19.3 GB).
void checkSampleMemory(const Volume& volume, const FromVdbOptions& o)
{
    if (o.maxMemoryBytes == 0) return;
    const std::size_t m = volume.sampleCount(o.band, o.samplesPerAxis);
    const double need = double(m) * double(fitBytesPerSample(volume.info().shDegree));
    const MemoryRoom room = memoryRoom(o.maxMemoryBytes);
    if (need <= room.left()) return;
    throw InputError(msg(volume.info().path, ": ", m, " training samples (", o.samplesPerAxis, "^3 per voxel, with a band of ",
                         o.band, ") need about ", formatBytes(need), ", more than ", room.text(),
                         "; lower --samples-per-voxel or --band, or raise --max-memory"));
}

} // namespace

std::uint64_t fitBytesPerVoxel(const FromVdbOptions& o)
{
    if (!o.fit) return 12 + 4 + 12; // --no-fit: the moment initialisation's voxels (VoxelSamples)
    const std::uint64_t n = std::uint64_t(o.samplesPerAxis);
    return n * n * n * fitBytesPerSample(0);
}

VolumeMeaning parseVolumeMeaning(const std::string& name)
{
    if (name == "auto") return VolumeMeaning::Auto;
    if (name == "field") return VolumeMeaning::Field;
    if (name == "extinction") return VolumeMeaning::Extinction;
    throw InputError(msg("unknown volume meaning '", name, "' (auto, field or extinction)"));
}

VolumeMeaning resolveMeaning(VolumeMeaning m, const Volume& volume)
{
    if (m != VolumeMeaning::Auto) return m;
    return volume.info().ownFile ? VolumeMeaning::Field : VolumeMeaning::Extinction;
}

double densityScale(VolumeMeaning resolved, const Volume& volume)
{
    if (resolved != VolumeMeaning::Extinction) return 1.0;
    // A quarter of the maximum: values below cutoff * scale are lost, overlapping splats reach the
    // peaks. --no-fit errors at max, max/2, max/4, max/8: wdas cloud 0.192, 0.178, 0.176, 0.201;
    // smoke 0.376, 0.217 (max/2.9), 0.167 (max/5.7), 0.159 (max/8).
    return std::max(double(volume.info().maxValue) / 4.0, 1e-30);
}

VolumeJudge makeVolumeJudge(const Volume& volume, double scale, const VolumeJudgeOptions& o)
{
    VolumeJudge j;
    j.points = volume.heldOutPoints(o.points, o.seed, o.band);
    FieldErrorTarget& t = j.target;
    t.shDegree = volume.info().shDegree;
    const std::size_t stride = std::size_t(volume.featureStride());
    std::vector<float> f(o.points * stride);
    t.opacity.resize(o.points);
    volume.sample(j.points.data(), o.points, t.opacity.data(), f.data());
    divide(t.opacity, scale);
    t.features.assign(f.begin(), f.end());
    for (double& x : t.features) x /= scale;
    for (double x : t.features) t.sumFeatures += std::fabs(x);
    for (float x : t.opacity) t.sumOpacity += x;
    j.features.filterVariance = float(volume.info().restFilterVariance());
    return j;
}

FieldErrorReport judgeModel(const VolumeJudge& judge, const GaussianCloud& model)
{
    return fieldError(judge.target, model, judge.points.data(), judge.features);
}

FromVdbOptions defaultFromVdbOptions()
{
    FromVdbOptions o;
    StageTwoOptions& s2 = o.fitting.stage2;
    s2.lrSh = 2.5e-3f; // 3DGS's f_dc rate: colours are fitted from the start here, not refined
    // Stage II's defaults refine a fitted model; here every Gaussian starts from its cluster's
    // moments, widened by the spread. Held-out errors (30 iterations, 1 per 8 voxels, wdas / smoke):
    // engine defaults 0.094 / 0.115; boundary weight 2 instead of 99 (a band sample outweighed 100
    // active ones and pinned the splats' skirts inside) 0.082 / ~0.10; with scale rate 2e-2 and
    // position rate 1e-3 0.070 / 0.099. Larger rates grow the coverage boxes (their reach is
    // coverageSteps steps), so they reach 5 steps (rebuilt every 5 then): smoke CPU 110 s -> 65 s.
    s2.boundaryWeight = 2.0f;
    s2.lrLogScale = 2e-2f;
    s2.lrPositionStart = 1e-3f;
    s2.coverageSteps = 5;
    // Step rejection and the bounded mean step guard a fitted model against climbing; from the
    // moments they hold the fit back (smoke, 45 iterations: 0.105 with both, 0.108 with the
    // rejection only, 0.084 with neither; the best iterate is still kept).
    s2.rejectSteps = false;
    s2.maxMeanStep = 0.0f;
    // Smoke needs 45 iterations for 2x (30: 1.88x); the engine since 0351c75 takes 44 s of CPU for them.
    o.fitting.iterations = 45;
    return o;
}

FromVdbResult fromVdb(const Volume& volume, const FromVdbOptions& o)
{
    Stopwatch total;
    const double cpu0 = cpuSeconds();
    const VolumeMeaning meaning = resolveMeaning(o.meaning, volume);
    const double scale = o.densityScale > 0 ? o.densityScale : densityScale(meaning, volume);
    VoxelSamples voxels = volume.activeVoxels();
    divide(voxels.values, scale);
    divide(voxels.features, scale);
    const std::size_t budget = o.gaussians > 0 ? o.gaussians : defaultGaussianBudget(voxels.size());
    MomentInitOptions init = o.init;
    init.gaussians = o.fit ? initialGaussianCount(budget, o.fitting) : budget;
    init.spread = o.spread > 0 ? o.spread : (meaning == VolumeMeaning::Extinction ? 1.5 : 1.0);
    // Our own files hold the rest-filtered field (the fit uses that filter too, setFitFilter).
    // playbot-31k round trip, --no-fit judged at the lattice: 0.471 -> 0.326; after 45 iterations
    // 0.151 -> 0.135 (colour 0.211 -> 0.195).
    init.filterVariance = volume.info().restFilterVariance();
    Stopwatch phase;
    FromVdbResult r;
    r.splats = initFromMoments(voxels, init);
    const double msInit = phase.ms();
    progress(msg("initialised ", r.splats.size(), " Gaussians from the moments of ", voxels.size(), " voxels"));
    voxels = VoxelSamples();
    phase.reset();
    const VolumeJudge judge = makeVolumeJudge(volume, scale, o.judge);
    nlohmann::json held = {{"noFit", fieldErrorJson(judgeModel(judge, r.splats))}};
    double msEval = phase.ms(), msFit = 0;
    nlohmann::json fit;
    if (o.fit) {
        phase.reset();
        checkSampleMemory(volume, o);
        SampleSet samples = volume.sampleSet(o.band, o.samplesPerAxis);
        divide(samples.targetO, scale);
        divide(samples.targetF, scale);
        VolumeFitOptions fo = o.fitting;
        setFitFilter(volume, o.samplesPerAxis, fo.stage2);
        fo.stage2.maxMemoryBytes = o.maxMemoryBytes;
        fo.stage2.memoryAdvice = "Lower --samples-per-voxel or --coverage-steps, or raise --max-memory if the machine has more";
        progress(msg("fitting ", r.splats.size(), " Gaussians to ", samples.sampleCount(), " samples, ", fo.iterations,
                     " iterations"));
        fit = fitJson(fitToSamples(r.splats, samples, budget, fo));
        msFit = phase.ms();
        phase.reset();
        held["fit"] = fieldErrorJson(judgeModel(judge, r.splats));
        msEval += phase.ms();
    }
    std::size_t capped = 0;
    if (meaning == VolumeMeaning::Extinction) capped = extinctionToOpacity(r.splats, scale);
    r.report = {{"input", inputJson(volume.info())},
                {"as", meaning == VolumeMeaning::Field ? "field" : "extinction"},
                {"densityScale", scale},
                {"gaussians", {{"budget", budget}, {"initial", init.gaussians}, {"final", r.splats.size()}}},
                {"fitted", o.fit},
                {"iterations", o.fit ? o.fitting.iterations : 0},
                {"band", o.band},
                {"spread", init.spread},
                {"samplesPerAxis", o.samplesPerAxis},
                {"heldOut", held},
                {"opacityCapped", capped},
                {"timingsMs", {{"init", msInit}, {"fit", msFit}, {"eval", msEval}, {"total", total.ms()}}},
                {"cpuSeconds", cpuSeconds() - cpu0}};
    if (o.fit) r.report["fit"] = fit;
    return r;
}

namespace {

/// Median over the splats of (s1 s2 s3)^{1/3}.
double medianScale(const GaussianCloud& g)
{
    std::vector<double> s(g.size());
    for (std::size_t i = 0; i < g.size(); ++i)
        s[i] = std::exp((double(g.logScales[3 * i]) + g.logScales[3 * i + 1] + g.logScales[3 * i + 2]) / 3.0);
    if (s.empty()) return 1.0;
    std::nth_element(s.begin(), s.begin() + std::ptrdiff_t(s.size() / 2), s.end());
    return s[s.size() / 2];
}

Image labelledPair(const Image& a, const Image& b, const char* la, const char* lb)
{
    const int band = 2 * kGlyphHeight + 8, gap = 4;
    Image out(a.width + b.width + gap, std::max(a.height, b.height) + band, 4, 0.0f);
    for (std::size_t i = 3; i < out.pixels.size(); i += 4) out.pixels[i] = 1.0f;
    auto paste = [&](const Image& im, int x0) {
        for (int y = 0; y < im.height; ++y)
            for (int x = 0; x < im.width; ++x)
                for (int c = 0; c < 4; ++c) out.at(x0 + x, band + y, c) = im.at(x, y, c);
    };
    paste(a, 0);
    paste(b, a.width + gap);
    const Vec3f white{1.0f, 1.0f, 1.0f};
    drawText(out, (a.width - textWidth(la, 2)) / 2, 4, la, 2, white);
    drawText(out, a.width + gap + (b.width - textWidth(lb, 2)) / 2, 4, lb, 2, white);
    return out;
}

} // namespace

Image renderVolumeComparison(const Volume& volume, VolumeMeaning resolved, const GaussianCloud& splats,
                             const Camera& camera, const RenderOptions& render)
{
    const double sigmaPerValue =
        resolved == VolumeMeaning::Extinction ? 1.0 : 1.0 / (std::sqrt(2.0 * M_PI) * medianScale(splats));
    const int stride = volume.featureStride();
    VolumeLookup lookup = [&](const float* p, std::size_t m, float* sigma, float* rgb) {
        std::vector<float> f(m * std::size_t(stride));
        volume.sample(p, m, sigma, f.data());
        for (std::size_t k = 0; k < m; ++k) {
            const float o = sigma[k];
            for (int c = 0; c < 3; ++c)
                rgb[3 * k + std::size_t(c)] = o > 0 ? std::max(0.0f, float(0.5 + kShC0 * f[k * std::size_t(stride) + std::size_t(c)] / o)) : 0.0f;
            sigma[k] = float(o * sigmaPerValue);
        }
    };
    Vec3d lo, hi;
    volume.worldBounds(lo, hi);
    RayMarchOptions ro;
    ro.step = 0.5 * volume.info().voxelSize;
    const Image marched = rayMarch(lookup, lo, hi, camera, ro);
    const Image rendered = renderGaussiansOn(splats, camera, render);
    return labelledPair(rendered, marched, "splats", "volume (ray marched)");
}

} // namespace splatwarp
