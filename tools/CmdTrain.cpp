/// `splatwarp train DATA -o MODEL.ply`: 3D Gaussian Splatting from posed pictures (train/Trainer.h).
#include "Command.h"
#include "ReadArgs.h"
#include "SharedArgs.h"
#include "TrainArgs.h"
#include "job/TrainJob.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Memory.h"
#include "io/GaussianIO.h"

namespace splatwarp::cli {
namespace {

struct TrainArgs {
    std::string data, output, init;
    std::size_t randomCount = 100000;
    DatasetOptions dataset;
    TrainFlags flags;
};

/// 3DGS's start without points: uniform in a cube around the cameras' mean, 0.3 x their extent
/// on each side of it (NeRF-synthetic cameras at radius 4 give about 3DGS's [-1.3, 1.3]^3).
GaussianCloud randomStart(const Dataset& data, std::size_t count, unsigned seed)
{
    Vec3d mean;
    for (const TrainingView& v : data.train) mean += v.camera.centre() / double(data.train.size());
    const double half = 0.3 * cameraExtent(data.train);
    return randomGaussians(mean - Vec3d(half, half, half), mean + Vec3d(half, half, half), count, seed);
}

void run(const TrainArgs& a)
{
    OutputSet outputs({a.data, a.init});
    outputs.checkTarget(a.output);
    if (!a.flags.report.empty()) outputs.checkTarget(a.flags.report);
    const TrainOptions options = a.flags.options();
    if (a.init.empty()) checkStartWithinCap("--random-points", a.randomCount, options.maxGaussians);
    DatasetOptions dataset = a.dataset;
    dataset.background = options.background;
    const Dataset data = readDataset(a.data, dataset);
    // Its pictures and camera files are inputs now (readWholeFile() added them): refused before training.
    outputs.checkNotInput(a.output);
    if (!a.flags.report.empty()) outputs.checkNotInput(a.flags.report);
    const GaussianCloud init = a.init.empty() ? randomStart(data, a.randomCount, options.seed) : readModel(a.init, false);
    const TrainOutcome out = trainAndScore(init, data, options);
    writePly(a.output, out.model);
    if (!a.flags.report.empty()) writeFileAtomic(a.flags.report, trainReportJson(out, data, options).dump(2) + "\n");
    outputs.commit();
    progress(msg("wrote ", out.model.size(), " Gaussians to ", a.output, " (", int(out.report.seconds), " s)"));
}

const CommandRegistrar reg(70, [](CLI::App& app) {
    auto a = std::make_shared<TrainArgs>();
    CLI::App* sub = app.add_subcommand(
        "train", "Train 3D Gaussian Splatting on posed pictures (NeRF-synthetic transforms_train/test.json with RGBA "
                 "PNGs, or graphdeco cameras.json + images/) on the CPU: the 3DGS recipe, held-out PSNR/SSIM at the end");
    sub->add_option("data", a->data, "Data folder")->required()->check(CLI::ExistingDirectory);
    sub->add_option("-o,--output", a->output, "Output .ply")->required();
    sub->add_option("--downscale", a->dataset.downscale, "Integer factor the pictures are box-filtered by (3DGS's -r)")
        ->capture_default_str()
        ->check(inRange(1, kMaxDownscale));
    addMaxMemoryOption(sub, a->dataset.maxMemoryBytes,
                       msg("Refuse a folder whose pictures would need more host memory than this at --downscale, sized "
                           "from their headers before any is decoded, and say which --downscale fits: 8G, 512M, ... "
                           "(default: 3/4 of physical memory, ",
                           formatBytes(double(defaultMemoryBudget())), " here)"));
    sub->add_option("--holdout", a->dataset.holdout, "graphdeco folders: every Nth view is held out for the report (0: none)")
        ->capture_default_str()
        ->check(nonNegative());
    sub->add_option("--init", a->init, "Start from this model instead of random points")->check(CLI::ExistingFile);
    sub->add_option("--random-points", a->randomCount, "Random starting Gaussians without --init")->capture_default_str()->check(positive());
    addTrainFlags(sub, a->flags);
    sub->callback([a] { run(*a); });
});

} // namespace
} // namespace splatwarp::cli
