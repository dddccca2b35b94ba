#pragma once
/// @file GaussianIO.h
/// @brief Reading and writing Gaussian models: graphdeco PLY (read any layout, write exactly
///        graphdeco), `.splat`, SuperSplat compressed PLY.
#include <string>
#include <vector>

#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief Options for readGaussians().
struct ReadOptions {
    /// Drop Gaussians with NaN/Inf values (and report how many) instead of refusing the file.
    bool dropInvalid = false;
};

/// @brief What a read found besides the Gaussians.
struct ReadReport {
    std::string format;               ///< "ply-binary-le", "ply-binary-be", "ply-ascii", "splat", "ply-compressed"
    std::size_t dropped = 0;          ///< Gaussians dropped by dropInvalid
    std::vector<std::string> notes;   ///< e.g. ignored extra properties
};

/// @brief Read any supported file, detected from its content (not its extension).
/// @throws InputError naming the file and what is wrong; IoError when it cannot be read.
GaussianCloud readGaussians(const std::string& path, const ReadOptions& options = {}, ReadReport* report = nullptr);

/// @brief Write graphdeco 3DGS PLY (binary little-endian, normals = 0, float32) atomically.
/// @throws InputError if the cloud holds NaN/Inf (a viewer would choke on it).
void writePly(const std::string& path, const GaussianCloud& cloud);

/// @brief The graphdeco property names in file order for a given SH degree.
std::vector<std::string> graphdecoPropertyNames(int shDegree);

} // namespace splatwarp
