#include "job/TrainJob.h"

#include <algorithm>
#include <filesystem>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Memory.h"
#include "core/Progress.h"
#include "core/SafePath.h"
#include "image/ImageIO.h"
#include "io/CameraFileWriter.h"

namespace splatwarp {

TrainOutcome trainAndScore(const GaussianCloud& init, const Dataset& data, const TrainOptions& options)
{
    TrainOutcome out;
    progress(msg("train: ", data.train.size(), " views of ", data.train.front().camera.width, "x",
                 data.train.front().camera.height, ", ", init.size(), " initial Gaussians, ", options.iterations, " steps"));
    out.model = trainGaussians(init, data.train, options, &out.report, [](const std::string& line) { progress(line); });
    if (!data.test.empty()) {
        out.test = scoreViews(out.model, data.test, options.background, options.threaded);
        progress(msg("train: held-out PSNR ", out.test.meanPsnr, " dB, SSIM ", out.test.meanSsim, " (", data.test.size(), " views)"));
    }
    return out;
}

nlohmann::json trainReportJson(const TrainOutcome& o, const Dataset& data, const TrainOptions& t)
{
    nlohmann::json views = nlohmann::json::array();
    for (std::size_t i = 0; i < o.test.names.size(); ++i)
        views.push_back({{"name", o.test.names[i]}, {"psnr", o.test.psnr[i]}, {"ssim", o.test.ssim[i]}});
    return {{"format", data.format},
            {"trainViews", data.train.size()},
            {"testViews", data.test.size()},
            {"width", data.train.empty() ? 0 : data.train.front().camera.width},
            {"height", data.train.empty() ? 0 : data.train.front().camera.height},
            {"iterations", o.report.iterations},
            {"gaussians", o.report.gaussians},
            {"seconds", o.report.seconds},
            {"finalLoss", o.report.finalLoss},
            {"test", {{"psnr", o.test.meanPsnr}, {"ssim", o.test.meanSsim}, {"views", views}}},
            {"options",
             {{"shDegree", t.shDegree}, {"densifyUntil", t.densifyUntil}, {"densifyInterval", t.densifyInterval},
              {"opacityResetInterval", t.opacityResetInterval}, {"shInterval", t.shInterval},
              {"background", {t.background.x, t.background.y, t.background.z}}, {"seed", t.seed}}}};
}

namespace {

/// Refuse views that would not fit o.maxMemoryBytes, before rendering any: they are all held while
/// training (4 floats a pixel), and `--views 100000` grew past 20 GB.
void checkViewMemory(const std::string& meshPath, const FromMeshOptions& o)
{
    if (o.maxMemoryBytes == 0) return;
    const std::size_t views = std::size_t(o.views.views) + std::size_t(std::max(o.testViews, 0));
    const double need = double(views) * double(o.views.width) * double(o.views.height) * 4.0 * sizeof(float);
    if (need <= double(o.maxMemoryBytes)) return;
    throw InputError(msg(meshPath, ": ", o.views.views, " + ", o.testViews, " views of ", o.views.width, "x", o.views.height,
                         " need ", formatBytes(need), ", over --max-memory ", formatBytes(double(o.maxMemoryBytes)),
                         ": fewer --views or --test-views, a smaller --size, or a larger --max-memory"));
}

} // namespace

TrainOutcome fromMesh(const std::string& meshPath, const FromMeshOptions& o, Dataset& data)
{
    checkViewMemory(meshPath, o);
    const TriangleMesh mesh = readMesh(meshPath, o.read);
    progress(msg("from-mesh: ", meshPath, ": ", mesh.vertexCount(), " vertices, ", mesh.triangleCount(), " triangles, ",
                 mesh.textures.size(), " textures"));
    MeshRenderOptions render = o.render;
    render.background = o.train.background;
    Stopwatch watch;
    data.format = "mesh";
    data.train = renderMeshViews(mesh, meshCameras(mesh, o.views), render);
    SphereViewOptions test = o.views;
    test.views = o.testViews;
    test.phase = 0.5;
    if (o.testViews > 0) data.test = renderMeshViews(mesh, meshCameras(mesh, test), render);
    for (TrainingView& v : data.test) v.camera.name = "test_" + v.camera.name;
    progress(msg("from-mesh: rendered ", data.train.size(), " + ", data.test.size(), " views in ", int(watch.ms()), " ms"));
    return trainAndScore(meshSurfaceGaussians(mesh, o.initGaussians, o.train.seed), data, o.train);
}

void checkViewsDir(OutputSet& outputs, const std::string& dir, bool withTest, const std::vector<std::string>& others)
{
    namespace fs = std::filesystem;
    const fs::path root(dir);
    checkSubfoldersAreFolders(dir, {"images", "test", "test/images"}, "--views-dir");
    for (const std::string& other : others)
        if (!other.empty() && (isWithin(other, dir) || isWithin((root / "images").string(), other) ||
                               isWithin((root / "test").string(), other)))
            throw IoError(msg(other, ": is where --views-dir ", dir, " writes its views; give it another path"));
    outputs.checkTarget((root / "cameras.json").string());
    if (withTest) outputs.checkTarget((root / "test" / "cameras.json").string());
}

void writeViews(const std::string& dir, const std::vector<TrainingView>& views)
{
    const std::filesystem::path images = std::filesystem::path(dir) / "images";
    OutputSet* outputs = OutputSet::active();
    if (outputs) outputs->createDirectory(images.string());
    else std::filesystem::create_directories(images);
    std::vector<Camera> cameras;
    for (const TrainingView& v : views) {
        writePng((images / (v.camera.name + ".png")).string(), v.image);
        cameras.push_back(v.camera);
    }
    writeGraphdecoCameras((std::filesystem::path(dir) / "cameras.json").string(), cameras);
}

} // namespace splatwarp
