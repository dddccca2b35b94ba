/// `splatwarp from-vdb IN.vdb -o OUT.ply`: fit Gaussians to an OpenVDB fog volume.
#include <cstdio>

#include "Command.h"
#include "job/FromVdb.h"
#include "SharedArgs.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "image/ImageIO.h"
#include "io/GaussianIO.h"

namespace splatwarp::cli {
namespace {

struct FromVdbArgs {
    std::string input, output, report, as = "auto";
    Device device = Device::Auto;
    bool render = false, noFit = false;
    int size = 512;
    VolumeReadOptions read;
    FromVdbOptions job = defaultFromVdbOptions();
};

/// OUT.ply -> OUT + suffix (the report and the picture sit beside the model).
std::string besideOutput(const std::string& out, const std::string& suffix)
{
    const std::size_t dot = out.rfind('.');
    const std::size_t slash = out.rfind('/');
    const bool hasExt = dot != std::string::npos && (slash == std::string::npos || dot > slash);
    return (hasExt ? out.substr(0, dot) : out) + suffix;
}

void addFitOptions(CLI::App* sub, FromVdbArgs& a)
{
    sub->add_option("--gaussians", a.job.gaussians, "Gaussian budget N (default 0: one per 8 active voxels)")
        ->capture_default_str()
        ->check(inRange(0, 1e9));
    sub->add_option("--iterations", a.job.fitting.iterations, "Stage II iterations (all rounds together)")
        ->capture_default_str()
        ->check(nonNegative());
    sub->add_option("--rounds", a.job.fitting.rounds,
                    "Fit rounds; between rounds transparent Gaussians are pruned and those with the largest "
                    "residual split (10% of the budget is held back for splits when > 1)")
        ->capture_default_str()
        ->check(inRange(1, 100));
    sub->add_option("--boundary-weight", a.job.fitting.stage2.boundaryWeight,
                    "lambda2: extra weight of samples with zero value (keeps splats out of empty space)")
        ->capture_default_str()
        ->check(nonNegative());
    sub->add_option("--band", a.job.band, "Empty voxels around the active region that train and judge")
        ->capture_default_str()
        ->check(inRange(0, 16));
    sub->add_option("--samples-per-voxel", a.job.samplesPerAxis,
                    "Training samples per voxel along each axis (trilinear targets; n^3 per voxel)")
        ->capture_default_str()
        ->check(inRange(1, 4));
    sub->add_option("--spread", a.job.spread,
                    "Initial standard deviations = moments times this (default 0: 1.5 for extinction, 1.0 for field)")
        ->capture_default_str()
        ->check(positive());
    StageTwoOptions& s2 = a.job.fitting.stage2;
    sub->add_option("--lr-position", s2.lrPositionStart, "Position learning rate at the start (times the volume's extent)")
        ->capture_default_str()
        ->check(nonNegative());
    sub->add_option("--lr-position-end", s2.lrPositionEnd, "Position learning rate at the end (exponential decay)")
        ->capture_default_str()
        ->check(nonNegative());
    sub->add_option("--lr-scale", s2.lrLogScale, "Log-scale learning rate")->capture_default_str()->check(nonNegative());
    sub->add_option("--lr-opacity", s2.lrOpacity, "Logit-opacity learning rate")->capture_default_str()->check(nonNegative());
    sub->add_option("--lr-sh", s2.lrSh, "SH learning rate")->capture_default_str()->check(nonNegative());
    sub->add_option("--lr-rotation", s2.lrRotation, "Quaternion learning rate")->capture_default_str()->check(nonNegative());
    addCoverageOptions(sub, s2);
    addMaxMeanStepOption(sub, s2);
    sub->add_option("--reject-steps", s2.rejectSteps,
                    "Undo a step that raises the training energy and retry at half the rates (true/false)")
        ->capture_default_str();
    sub->add_option("--density-scale", a.job.densityScale,
                    "Extinction per unit of fitted opacity (default 0: a quarter of the grid's maximum)")
        ->capture_default_str()
        ->check(nonNegative());
    sub->add_flag("--no-fit", a.noFit, "Stop after the moment initialisation (the baseline)");
    sub->add_option("--eval-points", a.job.judge.points, "Held-out points of the error in report.json")
        ->capture_default_str()
        ->check(positive());
    addMaxMemoryOption(sub, a.job.maxMemoryBytes,
                       msg("Refuse a volume whose fit would need more host memory than this, checked before the "
                           "grid is read (its active voxels), before the training samples are made (with the band) "
                           "and before Stage II's pair lists are: 8G, 512M, ... (default: 3/4 of physical memory, ",
                           formatBytes(double(defaultMemoryBudget())), " here)"));
}

const CommandRegistrar reg(45, [](CLI::App& app) {
    auto a = std::make_shared<FromVdbArgs>();
    CLI::App* sub = app.add_subcommand("from-vdb", "Fit Gaussians to an OpenVDB fog volume (graphdeco PLY + report)");
    sub->add_option("input", a->input, "Input .vdb (fog volume, level set, or our own to-vdb output)")->required();
    sub->add_option("-o,--output", a->output, "Output .ply (graphdeco)")->required();
    sub->add_option("--report", a->report, "report.json path (default: OUT with .report.json)");
    sub->add_option("--grid", a->read.grid, "FloatGrid to fit (default: density, else the only FloatGrid)");
    sub->add_option("--color-grid", a->read.colorGrid, "Vec3S colour grid (default: color or Cd when present; none: white)");
    sub->add_option("--as", a->as,
                    "field: the value is the splat opacity field (default for our own files); extinction: "
                    "extinction per world unit, splat opacities from the transmittance through their centre "
                    "(default for other fog volumes)")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "field", "extinction"}));
    addFitOptions(sub, *a);
    addDeviceOption(sub, a->device, "the Stage II fit and --render run");
    sub->add_flag("--render", a->render, "Also write OUT.png: the splats beside a ray-marched render of the volume");
    sub->add_option("--size", a->size, "Square size of each --render picture")->capture_default_str()->check(inRange(16, 4096));
    sub->callback([a] {
        a->job.meaning = parseVolumeMeaning(a->as);
        a->job.fit = !a->noFit;
        a->job.fitting.stage2.device = resolveDevice(a->device);
        a->read.memoryLimit = a->job.maxMemoryBytes;
        a->read.bytesPerVoxel = fitBytesPerVoxel(a->job);
        // Every output checked before the fit, and all of them appear together or not at all.
        OutputSet outputs({a->input});
        const std::string report = a->report.empty() ? besideOutput(a->output, ".report.json") : a->report;
        const std::string png = besideOutput(a->output, ".png");
        outputs.checkTarget(a->output);
        outputs.checkTarget(report);
        if (a->render) outputs.checkTarget(png);
        const Volume volume = readVolume(a->input, a->read);
        const VolumeInfo& info = volume.info();
        progress(msg("read '", printableLine(info.grid), "' from ", a->input, ": ", info.activeVoxels, " active voxels, voxel size ",
                     info.voxelSize, ", SH degree ", info.shDegree));
        for (const std::string& note : info.notes) progress("note: " + note);
        const FromVdbResult result = fromVdb(volume, a->job);
        Image picture;
        if (a->render) {
            OrbitOptions orbit;
            orbit.views = 1;
            orbit.width = orbit.height = a->size;
            RenderOptions render;
            render.device = a->job.fitting.stage2.device;
            picture = renderVolumeComparison(volume, resolveMeaning(a->job.meaning, volume), result.splats,
                                             orbitCameras(result.splats, orbit).front(), render);
        }
        writePly(a->output, result.splats);
        writeFileAtomic(report, result.report.dump(2) + "\n");
        if (a->render) writePng(png, picture);
        outputs.commit();
        const auto& held = result.report["heldOut"];
        std::printf("held-out density error: no-fit %.4f%s\n", held["noFit"]["opacity"].get<double>(),
                     held.contains("fit") ? msg(", fit ", held["fit"]["opacity"].get<double>()).c_str() : "");
    });
});

} // namespace
} // namespace splatwarp::cli
