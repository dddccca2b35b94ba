#pragma once
/// @file SogIO.h
/// @brief Writing PlayCanvas SOG (meta.json version 2 + lossless WebP images) with its options.
///        readGaussians() reads SOG by content (a `.sog` zip bundle) or by path (a file named
///        meta.json, or a folder holding one); writeGaussians() writes `.sog` and `DIR/meta.json`
///        with the default SogOptions. See docs/formats.md.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief How SOG is written: the higher-SH palette is k-means over the Gaussians' SH vectors.
struct SogOptions {
    int iterations = 10;           ///< k-means rounds (splat-transform's default)
    std::uint64_t seed = 1;        ///< picks the starting centroids: the same seed gives the same bytes
    std::size_t maxPalette = 65536; ///< cap on splat-transform's palette size (the largest power of two <= n, up to 64 K)
};

/// @brief The files of a SOG for a cloud, meta.json last: what the bundle holds and the folder form writes.
/// @throws InputError for an empty cloud, NaN/Inf, or more Gaussians than 16383x16383 WebP texels.
std::vector<std::pair<std::string, std::string>> encodeSogFiles(const std::string& path, const GaussianCloud& cloud,
                                                                 const SogOptions& options = {});
/// @brief The `.sog` bundle (a stored zip of encodeSogFiles()).
std::string encodeSog(const std::string& path, const GaussianCloud& cloud, const SogOptions& options = {});
/// @brief Write SOG: a path named meta.json gets the folder form (meta.json and the WebP images beside
///        it, written atomically, meta.json last; the folder is created with the active OutputSet),
///        any other path the `.sog` bundle.
void writeSog(const std::string& path, const GaussianCloud& cloud, const SogOptions& options = {});

} // namespace splatwarp
