#pragma once
/// @file GaussianIO.h
/// @brief Reading and writing Gaussian models: graphdeco PLY (read any layout, write exactly
///        graphdeco), `.splat`, SuperSplat compressed PLY, Niantic `.spz` (versions 2, 3).
#include <string>
#include <vector>

#include "core/GaussianCloud.h"

namespace splatwarp {

/// @brief Options for readGaussians().
struct ReadOptions {
    /// Drop unusable Gaussians (and report how many) instead of refusing the file: NaN/Inf values,
    /// or values finite on disk that overflow in use (|log-scale| > 40, |centre| > 1e15, a
    /// quaternion norm outside [1e-12, 1e18]).
    bool dropInvalid = false;
    /// Keep Gaussians with NaN/Inf values as read and only count them (for `info`); wins over
    /// dropInvalid. Default false: such files are refused.
    bool keepInvalid = false;
};

/// @brief What a read found besides the Gaussians.
struct ReadReport {
    std::string format;               ///< "ply-binary-le", "ply-binary-be", "ply-ascii", "splat", "ply-compressed", "spz-v2", "spz-v3"
    std::size_t dropped = 0;          ///< Gaussians dropped by dropInvalid
    std::size_t invalidValues = 0;    ///< NaN/Inf or unusable values found (before any drop)
    std::size_t invalidGaussians = 0; ///< Gaussians holding at least one of them
    std::vector<std::string> notes;   ///< e.g. ignored extra properties
};

/// @brief Read any supported file, detected from its content (not its extension): PLY (graphdeco
///        layout by property name, or SuperSplat compressed) when it starts with "ply", `.spz`
///        when it starts with the gzip magic, else `.splat` when its size is a multiple of 32
///        bytes and its records look like Gaussians.
/// @throws InputError naming the file and what is wrong (a Gaussian with NaN/Inf is named with
///         its index and property unless options say to drop or keep it); IoError when it
///         cannot be read.
GaussianCloud readGaussians(const std::string& path, const ReadOptions& options = {}, ReadReport* report = nullptr);

/// @brief readGaussians() of bytes already in memory (fuzzers, in-memory callers); `name` stands
///        for the file in messages.
GaussianCloud readGaussiansFromBytes(const std::string& name, const std::string& data, const ReadOptions& options = {},
                                     ReadReport* report = nullptr);

/// @brief Write graphdeco 3DGS PLY (binary little-endian, normals = 0, float32) atomically.
/// @throws InputError if the cloud holds NaN/Inf (a viewer would choke on it).
void writePly(const std::string& path, const GaussianCloud& cloud);

/// @brief The graphdeco property names in file order for a given SH degree.
std::vector<std::string> graphdecoPropertyNames(int shDegree);

/// @brief Graphdeco name of SH coefficient j (0 = f_dc) of colour channel c for a degree:
///        f_dc_c, or f_rest_{c*K'+j-1} with K' = (degree+1)^2 - 1.
std::string shPropertyName(int shDegree, int j, int c);

} // namespace splatwarp
