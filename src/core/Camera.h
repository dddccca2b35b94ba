#pragma once
/// @file Camera.h
/// @brief Pinhole cameras (OpenCV axes: x right, y down, z forward, as 3DGS). Orbit cameras and
///        the rasteriser's view live in render/Camera.h; camera files in io/CameraFiles.h.
#include <string>

#include "core/SmallMath.h"

namespace splatwarp {

/// Largest image side a camera file or --size may ask for: a 16384^2 RGBA float picture is 4 GiB,
/// beyond it a typo (or a hostile file) would only fail later in an allocation or an int overflow.
constexpr int kMaxImageSide = 16384;

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

    /// @brief Camera at `eye` looking at `target`, with `up` pointing up in the image.
    /// @param fovYDeg vertical field of view in degrees; the principal point is the image centre.
    static Camera lookAt(const Vec3d& eye, const Vec3d& target, const Vec3d& up, double fovYDeg, int width, int height);
    /// @brief Camera at `centre` with a camera-to-world rotation (OpenCV axes); intrinsics unset.
    static Camera fromCameraToWorld(const Mat3d& c2w, const Vec3d& centre);
};

/// @brief Degrees to radians.
inline double radians(double deg) { return deg * 3.14159265358979323846 / 180.0; }

} // namespace splatwarp
