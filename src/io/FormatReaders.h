#pragma once
/// @file FormatReaders.h
/// @brief The per-format readers behind readGaussians() (internal to src/io; readGaussians()
///        detects the format and applies the invalid-value policy).
#include <cstdint>
#include <string>

#include "core/GaussianCloud.h"
#include "io/GaussianIO.h"
#include "io/PlyBody.h"
#include "io/PlyHeader.h"

namespace splatwarp {

/// Alpha stored as u8 (.splat, compressed PLY) is clamped to [eps, 1 - eps] before the logit so
/// 0 and 255 stay finite; 1e-6 is what PlayCanvas splat-transform uses, so our values agree with
/// files it decoded (logit range about +-13.8).
constexpr double kU8AlphaEps = 1e-6;

/// @brief logit(clamp(a / 255, kU8AlphaEps, 1 - kU8AlphaEps)).
float logitOfU8Alpha(std::uint32_t a);

/// @brief Graphdeco PLY (any property order, any scalar types, SH degree from the f_rest count).
GaussianCloud readGraphdecoPly(const std::string& path, const PlyHeader& header, const PlyBody& body,
                               ReadReport& report);

/// @brief True when the header has the SuperSplat compressed layout (chunk + packed vertex).
bool isCompressedPly(const PlyHeader& header);
/// @brief SuperSplat compressed PLY: 256 Gaussians per chunk, quantised in chunk min/max.
GaussianCloud readCompressedPly(const std::string& path, const PlyHeader& header, const PlyBody& body,
                                ReadReport& report);

/// @brief Bytes per `.splat` record.
constexpr std::size_t kSplatRecordBytes = 32;
/// @brief antimatter15 `.splat`: headerless 32-byte records.
GaussianCloud readSplat(const std::string& path, const std::string& data, ReadReport& report);

} // namespace splatwarp
