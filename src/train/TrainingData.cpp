#include "train/TrainingData.h"

#include <filesystem>

#include "core/Error.h"
#include "image/TextureIO.h"
#include "io/CameraFiles.h"

namespace splatwarp {

namespace {

namespace fs = std::filesystem;

/// The picture a camera name stands for: the name itself or with .png/.jpg/.jpeg appended.
std::string findPicture(const fs::path& base, const std::string& name)
{
    for (const char* ext : {"", ".png", ".PNG", ".jpg", ".JPG", ".jpeg"}) {
        const fs::path p = base / (name + ext);
        if (fs::is_regular_file(p)) return p.string();
    }
    throw InputError(msg((base / name).string(), ": no picture for camera '", name, "' (tried .png and .jpg)"));
}

std::vector<TrainingView> loadViews(const std::string& cameraFile, const fs::path& pictures, const DatasetOptions& o)
{
    // Blender-style files give no size: a placeholder that each picture's own size then replaces.
    CameraFileOptions placeholder;
    placeholder.width = placeholder.height = 800;
    std::vector<TrainingView> out;
    for (const Camera& c : readCameraFile(cameraFile, placeholder)) {
        const Image picture = readTexture(findPicture(pictures, c.name));
        const Camera sized = c.width == picture.width && c.height == picture.height ? c : c.resized(picture.width, picture.height);
        out.push_back(makeTrainingView(sized, picture, o));
    }
    if (out.empty()) throw InputError(msg(cameraFile, ": no cameras"));
    return out;
}

} // namespace

TrainingView makeTrainingView(const Camera& camera, const Image& picture, const DatasetOptions& o)
{
    if (o.downscale < 1) throw InputError(msg("downscale must be at least 1, got ", o.downscale));
    const int f = o.downscale, w = picture.width / f, h = picture.height / f;
    if (w < 1 || h < 1) throw InputError(msg("camera '", camera.name, "': a ", picture.width, "x", picture.height, " picture downscaled by ", f, " is empty"));
    TrainingView v;
    // Cropping the remainder keeps the pixel grid: the camera scales by exactly 1/f.
    v.camera = camera.resized(picture.width, picture.height);
    v.camera.fx /= f;
    v.camera.fy /= f;
    v.camera.cx /= f;
    v.camera.cy /= f;
    v.camera.width = w;
    v.camera.height = h;
    v.image = Image(w, h, 3);
    const bool alpha = picture.channels == 4;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) {
                double sum = 0;
                for (int dy = 0; dy < f; ++dy)
                    for (int dx = 0; dx < f; ++dx) {
                        const int px = x * f + dx, py = y * f + dy;
                        const double a = alpha ? picture.at(px, py, 3) : 1.0;
                        sum += picture.at(px, py, c) * a + o.background[c] * (1.0 - a);
                    }
                v.image.at(x, y, c) = float(sum / (f * f));
            }
    return v;
}

Dataset readDataset(const std::string& dir, const DatasetOptions& o)
{
    const fs::path d(dir);
    if (!fs::is_directory(d)) throw InputError(msg(dir, ": not a folder"));
    Dataset ds;
    if (fs::is_regular_file(d / "transforms_train.json")) {
        ds.format = "nerf-synthetic";
        ds.train = loadViews((d / "transforms_train.json").string(), d, o);
        if (fs::is_regular_file(d / "transforms_test.json")) ds.test = loadViews((d / "transforms_test.json").string(), d, o);
        return ds;
    }
    if (fs::is_regular_file(d / "cameras.json")) {
        ds.format = "graphdeco";
        const fs::path images = fs::is_directory(d / "images") ? d / "images" : d;
        std::vector<TrainingView> all = loadViews((d / "cameras.json").string(), images, o);
        for (std::size_t i = 0; i < all.size(); ++i)
            (o.holdout > 0 && i % std::size_t(o.holdout) == 0 && all.size() > 1 ? ds.test : ds.train).push_back(std::move(all[i]));
        return ds;
    }
    throw InputError(msg(dir, ": neither transforms_train.json (NeRF synthetic) nor cameras.json (graphdeco) found"));
}

} // namespace splatwarp
