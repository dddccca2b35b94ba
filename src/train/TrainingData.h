#pragma once
/// @file TrainingData.h
/// @brief Posed pictures from disk: NeRF-synthetic folders (transforms_train.json and
///        transforms_test.json, RGBA PNGs) and graphdeco folders (cameras.json, images/).
#include <string>
#include <vector>

#include "image/TextureIO.h"
#include "train/Trainer.h"

namespace splatwarp {

/// The largest --downscale.
constexpr int kMaxDownscale = 64;

/// @brief Options for readDataset().
struct DatasetOptions {
    int downscale = 1;                  ///< integer factor, pictures box-filtered (3DGS's -r)
    Vec3f background{0.0f, 0.0f, 0.0f}; ///< RGBA pictures are composited over it
    int holdout = 8;                    ///< graphdeco folders: every holdout-th view is a test view (3DGS's llffhold)
    /// Refuse a folder whose pictures would need more memory than this at `downscale`, sized from
    /// their headers before any is decoded (0: no check).
    std::size_t maxMemoryBytes = 0;
};

/// @brief Memory the views of pictures of these sizes hold at `downscale` (3 floats a pixel), and
///        the most one picture needs while it is read (its file, bytes and floats, 4 channels).
double pictureMemoryBytes(const std::vector<PictureSize>& sizes, int downscale);

/// @brief Training and held-out views.
struct Dataset {
    std::vector<TrainingView> train, test;
    std::string format; ///< "nerf-synthetic" or "graphdeco"
};

/// @brief Read a folder (see the file note); images are PNG or JPEG, display values.
/// @throws InputError naming the folder or file that is missing or malformed, or the folder when
///         its pictures need more than options.maxMemoryBytes (with the --downscale that fits).
Dataset readDataset(const std::string& dir, const DatasetOptions& options = {});

/// @brief A picture made into a training view: composited over the background (when it has
///        alpha) and box-filtered by `downscale`, its camera resized to match.
TrainingView makeTrainingView(const Camera& camera, const Image& picture, const DatasetOptions& options);

} // namespace splatwarp
