#include "train/TrainingData.h"

#include <algorithm>
#include <cstdint>
#include <filesystem>

#include "core/Error.h"
#include "core/Memory.h"
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

/// A camera and the picture file it stands for.
struct PictureRef {
    Camera camera;
    std::string path;
};

std::vector<PictureRef> listPictures(const std::string& cameraFile, const fs::path& pictures)
{
    // Blender-style files give no size: a placeholder that each picture's own size then replaces.
    CameraFileOptions placeholder;
    placeholder.width = placeholder.height = 800;
    std::vector<PictureRef> out;
    for (const Camera& c : readCameraFile(cameraFile, placeholder)) out.push_back({c, findPicture(pictures, c.name)});
    if (out.empty()) throw InputError(msg(cameraFile, ": no cameras"));
    return out;
}

std::vector<TrainingView> loadViews(const std::vector<PictureRef>& refs, const DatasetOptions& o)
{
    std::vector<TrainingView> out;
    for (const PictureRef& r : refs) {
        const Image picture = readTexture(r.path);
        const Camera& c = r.camera;
        const Camera sized = c.width == picture.width && c.height == picture.height ? c : c.resized(picture.width, picture.height);
        out.push_back(makeTrainingView(sized, picture, o));
    }
    return out;
}

/// Refuse pictures that would not fit o.maxMemoryBytes, before decoding any: a folder of
/// full-size photographs read at --downscale 1 would otherwise fill the machine picture by picture.
void checkPictureMemory(const std::string& dir, const std::vector<PictureRef>& refs, const DatasetOptions& o)
{
    if (o.maxMemoryBytes == 0) return;
    std::vector<PictureSize> sizes;
    for (const PictureRef& r : refs) sizes.push_back(readTextureSize(r.path));
    const double budget = double(o.maxMemoryBytes);
    const double need = pictureMemoryBytes(sizes, o.downscale);
    if (need <= budget) return;
    int fits = o.downscale;
    while (fits < kMaxDownscale && pictureMemoryBytes(sizes, fits) > budget) ++fits;
    const std::string advice = pictureMemoryBytes(sizes, fits) <= budget ? msg("--downscale ", fits, " fits")
                                                                          : std::string("fewer pictures, or a larger --max-memory");
    throw InputError(msg(dir, ": its ", refs.size(), " pictures need ", formatBytes(need), " at --downscale ", o.downscale,
                         ", over the memory budget of ", formatBytes(budget), " (--max-memory): ", advice));
}

} // namespace

double pictureMemoryBytes(const std::vector<PictureSize>& sizes, int downscale)
{
    const std::int64_t f = std::max(downscale, 1);
    double kept = 0, largest = 0;
    for (const PictureSize& s : sizes) {
        kept += double(s.width / f) * double(s.height / f) * 3.0 * sizeof(float);
        largest = std::max(largest, double(s.width) * double(s.height) * 4.0 * (sizeof(float) + 2.0));
    }
    return kept + largest;
}

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
        const std::vector<PictureRef> train = listPictures((d / "transforms_train.json").string(), d);
        std::vector<PictureRef> test;
        if (fs::is_regular_file(d / "transforms_test.json")) test = listPictures((d / "transforms_test.json").string(), d);
        std::vector<PictureRef> all = train;
        all.insert(all.end(), test.begin(), test.end());
        checkPictureMemory(dir, all, o);
        ds.train = loadViews(train, o);
        ds.test = loadViews(test, o);
        return ds;
    }
    if (fs::is_regular_file(d / "cameras.json")) {
        ds.format = "graphdeco";
        const fs::path images = fs::is_directory(d / "images") ? d / "images" : d;
        const std::vector<PictureRef> refs = listPictures((d / "cameras.json").string(), images);
        checkPictureMemory(dir, refs, o);
        std::vector<TrainingView> all = loadViews(refs, o);
        for (std::size_t i = 0; i < all.size(); ++i)
            (o.holdout > 0 && i % std::size_t(o.holdout) == 0 && all.size() > 1 ? ds.test : ds.train).push_back(std::move(all[i]));
        return ds;
    }
    throw InputError(msg(dir, ": neither transforms_train.json (NeRF synthetic) nor cameras.json (graphdeco) found"));
}

} // namespace splatwarp
