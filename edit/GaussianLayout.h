#pragma once
/// @file GaussianLayout.h
/// @brief The editor's binary layout of a Gaussian model (GET /api/model, POST /api/pose,
///        GET /api/refined; docs/editor-api.md): a 16-byte header, then float32 arrays one after
///        another (structure of arrays, little-endian), so the page reads each as a Float32Array.
#include <cstdint>
#include <string>

#include "core/GaussianCloud.h"

namespace splatwarp::edit {

/// First four bytes of every encoded model.
constexpr char kLayoutMagic[4] = {'S', 'W', 'G', '1'};
/// Header bytes before the first array.
constexpr std::size_t kLayoutHeaderBytes = 16;
/// Floats per Gaussian of a model: means 3, rotations 4, log scales 3, opacity logit 1, SH DC 3.
constexpr std::size_t kLayoutFloats = 14;
/// Floats per Gaussian of a pose (POST /api/pose): means, rotations and log scales only; a pose
/// leaves opacities and colours as they are (the reader takes them from GET /api/model).
constexpr std::size_t kPoseFloats = 10;

/// @brief Encode: "SWG1", uint32 count N, uint32 floats per Gaussian (14), uint32 SH degree of
///        the model; then means [N,3], rotations [N,4] (w,x,y,z as stored), logScales [N,3],
///        opacity logits [N], SH DC [N,3] (f_dc RGB), all float32, the model's raw values bit for bit.
///        modelShDegree >= 0 is written as the SH degree instead of the cloud's (a preview holds DC only).
std::string encodeGaussians(const GaussianCloud& cloud, int modelShDegree = -1);

/// @brief A pose: the same header with 10 floats per Gaussian, then means, rotations and logScales.
std::string encodePose(const GaussianCloud& cloud, int modelShDegree);

/// @brief Decode a buffer of encodeGaussians() into a cloud of SH degree 0 (tests, bench); one of
///        encodePose() takes its opacities and DC from `rest`.
/// @throws InputError when the header or the size is wrong, or a pose comes without its rest model.
GaussianCloud decodeGaussians(const std::string& bytes, const GaussianCloud* rest = nullptr);

} // namespace splatwarp::edit
