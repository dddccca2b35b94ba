#pragma once
/// @file CameraFileWriter.h
/// @brief Writing cameras as graphdeco `cameras.json` (what io/CameraFiles.h reads back).
#include <string>
#include <vector>

#include "core/Camera.h"

namespace splatwarp {

/// @brief Write [{id, img_name, width, height, position, rotation (camera-to-world rows), fx, fy}]
///        atomically. The principal point is not stored: the format assumes the image centre.
/// @throws InputError for a camera whose principal point is off the centre; IoError on write failure.
void writeGraphdecoCameras(const std::string& path, const std::vector<Camera>& cameras);

} // namespace splatwarp
