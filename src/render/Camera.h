#pragma once
/// @file Camera.h
/// @brief Orbit cameras around a model and the rasteriser's view of a camera (core/Camera.h).
#include <string>
#include <vector>

#include "core/Camera.h"
#include "core/Outliers.h"
#include "core/GaussianCloud.h"
#include "core/SmallMath.h"
#include "render/SplatProjection.h"

namespace splatwarp {

/// @brief The float camera data the rasteriser needs.
PinholeView pinholeView(const Camera& camera);

/// @brief The most cameras one orbit or sphere of views places: 1e8 views held 22 GB of cameras
///        before the first render (`render --orbit`, `eval --views`, `from-mesh --views`).
constexpr int kMaxViews = 100000;

/// @brief Options for orbitCameras(); the CLI flags of `render` map onto these.
struct OrbitOptions {
    int views = 8;                ///< cameras evenly spaced in azimuth, the first one at azimuth 0
    double elevationDeg = 20.0;   ///< height of the orbit above the model's equator, degrees
    double fovDeg = 40.0;         ///< vertical field of view, degrees
    /// Distance from the box centre in units of the distance at which the bounding sphere of the
    /// (robust) box just fits the field of view; > 1 leaves a margin.
    double distanceFactor = 1.1;
    int width = 512, height = 512; ///< image size
    /// Up axis: "x", "y", "z", "-x", "-y", "-z", or "auto": the axis of the smallest extent,
    /// pointing away from the end where the centres crowd when they clearly do (by more than a
    /// quarter of the extent: a ground patch or a base, as in y-down captures), else +.
    std::string up = "auto";
    /// Fraction of centres ignored at each end of each axis when bounding the model, so that a few
    /// far floaters of a trained model do not shrink it to a dot.
    double boundsQuantile = kBulkQuantile;
};

/// @brief Unit vector of an up-axis name ("x", "-y", ...). "auto" is not accepted here.
/// @throws InputError for an unknown name.
Vec3d parseUpAxis(const std::string& name);

/// @brief Options for sphereCameras().
struct SphereViewOptions {
    int views = 100;              ///< directions of a Fibonacci lattice over the whole sphere
    double fovDeg = 40.0;         ///< vertical field of view, degrees
    double distanceFactor = 1.1;  ///< as OrbitOptions::distanceFactor, for the sphere of `radius`
    int width = 256, height = 256;
    Vec3d up{0.0, 1.0, 0.0};      ///< image up where the view allows it (rolls only; any axis will do)
    double phase = 0.0;           ///< lattice offset in [0, 1): another set of directions, e.g. held-out views
};

/// @brief Cameras looking at `centre` from directions spread evenly over the sphere, at the
///        distance where a sphere of `radius` just fits the view (times the distance factor).
/// @throws InputError for invalid options or a radius that is not positive.
std::vector<Camera> sphereCameras(const Vec3d& centre, double radius, const SphereViewOptions& options = {});

/// @brief Cameras on a circle around the model's robust bounding box.
/// @throws InputError for an empty model or invalid options.
std::vector<Camera> orbitCameras(const GaussianCloud& cloud, const OrbitOptions& options = {});

} // namespace splatwarp
