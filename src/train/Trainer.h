#pragma once
/// @file Trainer.h
/// @brief 3D Gaussian Splatting optimisation from posed pictures on the CPU (Kerbl et al. 2023's
///        recipe): Adam with its learning rates and exponential position-rate decay, loss
///        (1 - 0.2) L1 + 0.2 D-SSIM, SH degree raised over time, clone/split by view-space
///        gradient, pruning and periodic opacity reset.
#include <functional>
#include <string>
#include <vector>

#include "core/Camera.h"
#include "core/GaussianCloud.h"
#include "image/Image.h"

namespace splatwarp {

/// @brief A posed picture: RGB display values, already composited over the training background.
struct TrainingView {
    Camera camera;
    Image image;
};

/// @brief The recipe. Step counts are those of 3DGS's 30,000-step run; compressedSchedule()
///        scales them to a shorter run.
struct TrainOptions {
    int iterations = 30000;
    double positionLrStart = 1.6e-4; ///< x scene extent, decays exponentially to positionLrEnd
    double positionLrEnd = 1.6e-6;   ///< x scene extent, reached at the last iteration
    double featureLr = 2.5e-3;       ///< SH band 0
    double featureRestLr = 2.5e-3 / 20; ///< SH bands 1..3
    double opacityLr = 0.025;
    double scalingLr = 5e-3;
    double rotationLr = 1e-3;
    double lambdaDssim = 0.2;
    int shDegree = 3;          ///< highest SH degree, reached one band per shInterval steps
    int shInterval = 1000;
    int densifyFrom = 500, densifyUntil = 15000, densifyInterval = 100;
    int opacityResetInterval = 3000;
    double densifyGradThreshold = 2e-4; ///< mean |dL/d(NDC position)| over the views that saw it
    double percentDense = 0.01;         ///< clone at most this x extent in size, split above it
    double pruneOpacity = 0.005;
    double maxScreenRadius = 20;        ///< pixels; prunes (with > 0.1 x extent) after the first reset
    std::size_t maxGaussians = 2000000; ///< densification stops adding beyond this count
    Vec3f background{0.0f, 0.0f, 0.0f}; ///< what the pictures were composited over
    unsigned seed = 0;
    bool threaded = true;
    int progressEvery = 500; ///< a progress line every this many steps (0: none)
};

/// @brief The 30,000-step schedule scaled to `iterations` (every step count times iterations /
///        30000, at least 1; the densification interval at least 25), the learning rates unchanged.
TrainOptions compressedSchedule(int iterations);

/// @brief Image metrics of a model on a set of views.
struct ViewScores {
    std::vector<std::string> names;
    std::vector<double> psnr, ssim; ///< per view (image/Metrics.h)
    double meanPsnr = 0, meanSsim = 0;
};

/// @brief Render every view (over `background`) and score it against its picture.
ViewScores scoreViews(const GaussianCloud& cloud, const std::vector<TrainingView>& views, const Vec3f& background,
                      bool threaded = true);

/// @brief What a run did.
struct TrainReport {
    int iterations = 0;
    std::size_t gaussians = 0;
    double seconds = 0;
    double finalLoss = 0; ///< mean loss of the last 100 steps
};

/// @brief Scene extent as 3DGS defines it: 1.1 x the largest distance of a camera centre from their mean.
double cameraExtent(const std::vector<TrainingView>& views);

/// @brief Optimise `init` (any SH degree; raised to options.shDegree) on the views.
/// @param progress receives one line per options.progressEvery steps (may be empty)
/// @throws InputError for no views, an empty model or pictures whose size differs from their camera.
GaussianCloud trainGaussians(const GaussianCloud& init, const std::vector<TrainingView>& views,
                             const TrainOptions& options, TrainReport* report = nullptr,
                             const std::function<void(const std::string&)>& progress = {});

/// @brief Random initial Gaussians (3DGS's init without points): `count` centres uniform in the
///        box, grey, opacity 0.1, isotropic scale of the mean spacing.
GaussianCloud randomGaussians(const Vec3d& lo, const Vec3d& hi, std::size_t count, unsigned seed);

} // namespace splatwarp
