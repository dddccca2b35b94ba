#pragma once
/// @file Camera.h
/// @brief Pinhole cameras (OpenCV axes: x right, y down, z forward, as 3DGS), orbit cameras
///        around a model, and camera files (graphdeco cameras.json, NeRF transforms.json).
#include <string>
#include <vector>

#include "core/GaussianCloud.h"
#include "core/SmallMath.h"
#include "render/SplatProjection.h"

namespace splatwarp {

/// @brief A pinhole camera: x_cam = rotation * x_world + translation, pixel = (fx x/z + cx, fy y/z + cy)
///        with pixel (i, j) sampled at (i + 0.5, j + 0.5).
struct Camera {
    Mat3d rotation = Mat3d::identity(); ///< world-to-camera rotation
    Vec3d translation;                  ///< world-to-camera translation
    double fx = 0, fy = 0;              ///< focal lengths in pixels
    double cx = 0, cy = 0;              ///< principal point in pixels
    int width = 0, height = 0;          ///< image size in pixels
    std::string name;                   ///< image name from a camera file, or "view_NNN"

    /// @brief Camera centre in world space: -rotation^T translation.
    Vec3d centre() const;
    /// @brief The same view at another resolution (intrinsics scaled per axis).
    Camera resized(int newWidth, int newHeight) const;
    /// @brief The float camera data the rasteriser needs.
    PinholeView view() const;

    /// @brief Camera at `eye` looking at `target`, with `up` pointing up in the image.
    /// @param fovYDeg vertical field of view in degrees; the principal point is the image centre.
    static Camera lookAt(const Vec3d& eye, const Vec3d& target, const Vec3d& up, double fovYDeg, int width, int height);
};

/// @brief Options for orbitCameras(); the CLI flags of `render` map onto these.
struct OrbitOptions {
    int views = 8;                ///< cameras evenly spaced in azimuth, the first one at azimuth 0
    double elevationDeg = 20.0;   ///< height of the orbit above the model's equator, degrees
    double fovDeg = 40.0;         ///< vertical field of view, degrees
    /// Distance from the box centre in units of the distance at which the bounding sphere of the
    /// (robust) box just fits the field of view; > 1 leaves a margin.
    double distanceFactor = 1.1;
    int width = 512, height = 512; ///< image size
    /// Up axis: "x", "y", "z", "-x", "-y", "-z", or "auto" (+ the axis of the smallest extent).
    std::string up = "auto";
    /// Fraction of centres ignored at each end of each axis when bounding the model, so that a few
    /// far floaters of a trained model do not shrink it to a dot.
    double boundsQuantile = 0.01;
};

/// @brief Unit vector of an up-axis name ("x", "-y", ...). "auto" is not accepted here.
/// @throws InputError for an unknown name.
Vec3d parseUpAxis(const std::string& name);

/// @brief Cameras on a circle around the model's robust bounding box.
/// @throws InputError for an empty model or invalid options.
std::vector<Camera> orbitCameras(const GaussianCloud& cloud, const OrbitOptions& options = {});

/// @brief Options for readCameraFile().
struct CameraFileOptions {
    /// Image size used when the file does not give one (Blender-style transforms.json); 0 = none.
    int width = 0, height = 0;
};

/// @brief Read graphdeco `cameras.json` (a list of {id, img_name, width, height, position,
///        rotation (3x3 camera-to-world, rows), fx, fy}) or NeRF `transforms.json`
///        ({camera_angle_x or fl_x/fl_y, w/h, cx/cy, frames: [{file_path, transform_matrix (4x4
///        camera-to-world, OpenGL axes)}]}, per-frame intrinsics override the top level).
///        The format is detected from the content.
/// @throws InputError naming the file and the element when it is malformed; IoError when unreadable.
std::vector<Camera> readCameraFile(const std::string& path, const CameraFileOptions& options = {});

/// @brief readCameraFile() of JSON text already in memory; `path` names it in messages.
std::vector<Camera> parseCameraFile(const std::string& jsonText, const std::string& path,
                                    const CameraFileOptions& options = {});

} // namespace splatwarp
