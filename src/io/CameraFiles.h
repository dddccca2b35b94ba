#pragma once
/// @file CameraFiles.h
/// @brief Camera files: graphdeco `cameras.json` and NeRF `transforms.json`.
#include <string>
#include <vector>

#include "core/Camera.h"

namespace splatwarp {

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
