#pragma once
/// @file FormatReaders.h
/// @brief The per-format readers behind readGaussians() (internal to src/io; readGaussians()
///        detects the format and applies the invalid-value policy).
#include <cstdint>
#include <string>
#include <vector>

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
/// @brief Why `data` (a multiple of 32 bytes) does not read as `.splat` records, "" when at least
///        90% of the records with finite values look like Gaussians.
std::string splatImplausibility(const std::string& data);
/// @brief Why one 32-byte `.splat` record does not look like a Gaussian to readSplat(), "" when it
///        does; the writer refuses what its reader would take for corrupt data.
std::string splatRecordImplausibility(const unsigned char* record);
/// @brief antimatter15 `.splat`: headerless 32-byte records. The format has no magic: throws
///        InputError unless nearly all records look like Gaussians (finite, |position| and
///        scales <= 1e7, unit quaternion bytes), so text or a cut .vdb is not read as Gaussians.
GaussianCloud readSplat(const std::string& path, const std::string& data, ReadReport& report);

/// @brief True when the data starts like an `.spz`: gzip magic (versions 2, 3) or "NGSP" (version 4).
bool hasSpzMagic(const std::string& data);
/// @brief Niantic `.spz` versions 2 and 3 (gzip; the inflated size is capped by the header's count)
///        and 4 (NGSP header, one zstd stream per attribute, each checked against the count).
GaussianCloud readSpz(const std::string& path, const std::string& data, ReadReport& report);

/// @brief The order writeCompressedPly() stores Gaussians in: by the Morton code of their centres
///        (10 bits an axis over the bounding box), so each 256-Gaussian chunk is compact.
std::vector<std::size_t> compressedPlyOrder(const GaussianCloud& g);

/// @brief True when the data starts with the GLB magic "glTF".
bool hasGlbMagic(const std::string& data);
/// @brief glTF 2.0 binary with KHR_gaussian_splatting primitives (every one, concatenated), turned
///        from glTF's axes to graphdeco's (turnAboutZ()).
GaussianCloud readGlb(const std::string& path, const std::string& data, ReadReport& report);
/// @brief Turn every Gaussian (centre, orientation, SH) by 180 degrees about Z: graphdeco (COLMAP:
///        x right, y down, z forward) <-> glTF (x left, y up, z forward); its own inverse.
void turnAboutZ(GaussianCloud& g);

/// @brief True when a path names a SOG folder: a file named meta.json, or a folder holding one.
bool isSogFolderPath(const std::string& path);
/// @brief PlayCanvas SOG (meta.json version 2 + lossless WebP images) in a `.sog` zip bundle. Sizes are
///        checked before anything is inflated or decoded: the count against the image bytes, each
///        image's declared size against the count, zip entries against what the count can need.
GaussianCloud readSog(const std::string& path, const std::string& data, ReadReport& report);
/// @brief SOG as a folder: `path` is its meta.json (or the folder); only the images meta.json names,
///        plain file names beside it, regular files (no symlinks), are read.
GaussianCloud readSogFolder(const std::string& path, ReadReport& report);

/// @brief The formats registered with registerModelFormat(), in registration order.
std::vector<ModelFormatHooks> registeredModelFormats();

} // namespace splatwarp
