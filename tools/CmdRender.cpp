/// `splatwarp render IN -o OUT.png|OUT.exr|DIR [--orbit N | --camera FILE] ...`: splat renders.
#include <cstdio>
#include <filesystem>

#include "Command.h"
#include "SharedArgs.h"
#include "ReadArgs.h"
#include "RenderArgs.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "image/ImageIO.h"
#include "io/CameraFiles.h"
#include "io/GaussianIO.h"
#include "render/Camera.h"
#include "render/RenderDevice.h"

namespace splatwarp::cli {
namespace {

struct RenderArgs {
    std::string input, output, size, cameraFile, background = "0,0,0", format = "png";
    Device device = Device::Auto;
    int orbit = 0;
    bool dropInvalid = false;
    OrbitOptions orbitOptions;
};

void run(const RenderArgs& a)
{
    OutputSet outputs({a.input, a.cameraFile});
    const std::string ext = std::filesystem::path(a.output).extension().string();
    if (!ext.empty() && !isImagePath(a.output) && !std::filesystem::is_directory(a.output))
        throw UsageError(msg("-o ", a.output, ": unsupported image extension '", ext,
                             "' (supported: .png, .exr; a directory name for several views)"));
    const GaussianCloud cloud = readModel(a.input, a.dropInvalid);
    int width = 0, height = 0;
    if (!a.size.empty()) parseImageSize(a.size, width, height);
    RenderOptions renderOptions;
    renderOptions.background = parseColour(a.background);
    renderOptions.device = resolveDevice(a.device);

    std::vector<Camera> cameras;
    if (!a.cameraFile.empty()) {
        CameraFileOptions fileOptions;
        fileOptions.width = width;
        fileOptions.height = height;
        cameras = readCameraFile(a.cameraFile, fileOptions);
        if (width > 0)
            for (Camera& c : cameras) c = c.resized(width, height);
    } else {
        OrbitOptions o = a.orbitOptions;
        o.views = a.orbit > 0 ? a.orbit : 1;
        if (width > 0) {
            o.width = width;
            o.height = height;
        }
        cameras = orbitCameras(cloud, o);
    }

    // One camera and an image path: a single file. Otherwise -o is a directory of view_NNN files.
    const bool single = isImagePath(a.output) && cameras.size() == 1 && a.orbit == 0;
    if (!single) {
        if (isImagePath(a.output))
            throw UsageError(msg("-o ", a.output, ": ", cameras.size(), " views need a directory, not an image file"));
        outputs.createDirectory(a.output);
    } else {
        outputs.checkTarget(a.output);
    }
    for (std::size_t i = 0; i < cameras.size(); ++i) {
        Stopwatch watch;
        Device used = Device::Cpu;
        const Image image = renderGaussiansOn(cloud, cameras[i], renderOptions, &used);
        char name[32];
        std::snprintf(name, sizeof(name), "view_%03zu.%s", i, a.format.c_str());
        const std::string path = single ? a.output : (std::filesystem::path(a.output) / name).string();
        writeImage(path, image);
        progress(msg("rendered ", cloud.size(), " Gaussians at ", image.width, "x", image.height, " on ",
                     deviceName(used), " in ", int(watch.ms()), " ms -> ", path));
    }
    outputs.commit(); // every view or none
}

const CommandRegistrar reg(60, [](CLI::App& app) {
    auto args = std::make_shared<RenderArgs>();
    CLI::App* sub = app.add_subcommand("render", "Render a Gaussian model to PNG (the splat colours as they are: display values) or EXR (their linear decode, RGBA) with the splat rasteriser (CPU or CUDA)");
    sub->add_option("input", args->input, "Input Gaussian file " + kModelFormats)->required();
    sub->add_option("-o,--output", args->output,
                    "Output image (.png/.exr) for one view, or a directory receiving view_000.png ... for several")
        ->required();
    sub->add_option("--size", args->size,
                    "Image size WIDTHxHEIGHT (default 512x512 for orbits; camera files: their own size, rescaled when given)");
    // Capped as eval's and from-mesh's --views: 1e8 views held 22 GB of cameras before the first render.
    auto* orbit = sub->add_option("--orbit", args->orbit, "Render N views on an orbit around the model into the -o directory")
                      ->check(inRange(1, kMaxViews));
    sub->add_option("--camera", args->cameraFile, "Camera file: graphdeco cameras.json or NeRF transforms.json")
        ->check(CLI::ExistingFile)
        ->excludes(orbit);
    sub->add_option("--elevation", args->orbitOptions.elevationDeg, "Orbit elevation above the model's equator, degrees")
        ->capture_default_str()
        ->check(openInterval(-90.0, 90.0));
    sub->add_option("--fov", args->orbitOptions.fovDeg, "Orbit cameras' vertical field of view, degrees")
        ->capture_default_str()
        ->check(openInterval(0.0, 180.0));
    sub->add_option("--distance", args->orbitOptions.distanceFactor,
                    "Orbit distance as a multiple of the distance at which the model's bounding sphere just fits")
        ->capture_default_str()
        ->check(positive());
    sub->add_option("--up", args->orbitOptions.up, "Orbit up axis: x, y, z, -x, -y, -z or auto (the smallest extent, pointing away from the end where the centres crowd: y-down captures stand upright)")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "x", "y", "z", "-x", "-y", "-z", "+x", "+y", "+z"}));
    sub->add_option("--background", args->background, "Background colour r,g,b (display values 0..1, as the splat colours; 1,1,1 is white)")->capture_default_str();
    sub->add_option("--format", args->format, "Image format of the files written into an output directory")
        ->capture_default_str()
        ->check(CLI::IsMember({"png", "exr"}));
    addDeviceOption(sub, args->device, "to render");
    addDropInvalidFlag(sub, args->dropInvalid);
    sub->callback([args] { run(*args); });
});

} // namespace
} // namespace splatwarp::cli
