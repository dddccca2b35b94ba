/// `splatwarp from-mesh MESH -o MODEL.ply`: splats trained on views rendered around a mesh.
#include <filesystem>

#include "Command.h"
#include "SharedArgs.h"
#include "TrainArgs.h"
#include "job/TrainJob.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "io/GaussianIO.h"
#include "render/Camera.h"

namespace splatwarp::cli {
namespace {

struct FromMeshArgs {
    std::string mesh, output, viewsDir;
    int size = 256;
    FromMeshOptions options;
    TrainFlags flags;
};

void run(FromMeshArgs a)
{
    OutputSet outputs({a.mesh, a.options.read.texture});
    outputs.checkTarget(a.output);
    if (!a.flags.report.empty()) outputs.checkTarget(a.flags.report);
    if (!a.viewsDir.empty()) checkViewsDir(outputs, a.viewsDir, a.options.testViews > 0, {a.output, a.flags.report});
    a.options.train = a.flags.options();
    checkStartWithinCap("--init-gaussians", a.options.initGaussians, a.options.train.maxGaussians);
    a.options.views.width = a.options.views.height = a.size;
    Dataset data;
    const TrainOutcome out = fromMesh(a.mesh, a.options, data);
    writePly(a.output, out.model);
    if (!a.viewsDir.empty()) {
        writeViews(a.viewsDir, data.train);
        if (!data.test.empty()) writeViews((std::filesystem::path(a.viewsDir) / "test").string(), data.test);
    }
    if (!a.flags.report.empty()) writeFileAtomic(a.flags.report, trainReportJson(out, data, a.options.train).dump(2) + "\n");
    outputs.commit();
    progress(msg("wrote ", out.model.size(), " Gaussians to ", a.output, " (", int(out.report.seconds), " s)"));
}

const CommandRegistrar reg(71, [](CLI::App& app) {
    auto a = std::make_shared<FromMeshArgs>();
    a->flags.iterations = 7000;
    CLI::App* sub = app.add_subcommand(
        "from-mesh", "Turn a mesh (OBJ, PLY, glTF, OFF ... with textures or vertex colours, unlit) into splats: render "
                     "views spread over the sphere around it, train from samples of its surface, score held-out views");
    sub->add_option("mesh", a->mesh, "Mesh file")->required();
    sub->add_option("-o,--output", a->output, "Output .ply")->required();
    sub->add_option("--views", a->options.views.views, "Training views")->capture_default_str()->check(inRange(1, kMaxViews));
    sub->add_option("--test-views", a->options.testViews, "Held-out views (another set of directions)")
        ->capture_default_str()
        ->check(inRange(0, kMaxViews));
    sub->add_option("--size", a->size, "Square view size in pixels")->capture_default_str()->check(inRange(8, kMaxImageSide));
    sub->add_option("--fov", a->options.views.fovDeg, "Vertical field of view, degrees")->capture_default_str()->check(openInterval(0.0, 180.0));
    sub->add_option("--samples", a->options.render.samples, "Mesh samples per pixel axis (anti-aliasing)")
        ->capture_default_str()
        ->check(inRange(1, 8));
    sub->add_option("--texture", a->options.read.texture, "Texture for materials without one (an OBJ without .mtl)")
        ->check(CLI::ExistingFile);
    sub->add_flag("--procedural-colour", a->options.read.proceduralColour,
                  "Colour the mesh with smooth sinusoids of the position (for meshes without colour)");
    sub->add_option("--init-gaussians", a->options.initGaussians, "Gaussians sampled on the surface to start from")
        ->capture_default_str()
        ->check(positive());
    sub->add_option("--views-dir", a->viewsDir, "Also write the views used: DIR/cameras.json + DIR/images/*.png (held-out ones under DIR/test)");
    addMaxMemoryOption(sub, a->options.maxMemoryBytes,
                       msg("Refuse views that would need more host memory than this (all are held while training, "
                           "4 floats a pixel), before any is rendered: 8G, 512M, ... (default: 3/4 of physical memory, ",
                           formatBytes(double(defaultMemoryBudget())), " here)"));
    addTrainFlags(sub, a->flags);
    sub->callback([a] { run(*a); });
});

} // namespace
} // namespace splatwarp::cli
