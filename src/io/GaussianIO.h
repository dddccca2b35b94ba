#pragma once
/// @file GaussianIO.h
/// @brief Reading and writing Gaussian models: graphdeco PLY (read any layout, write exactly
///        graphdeco), `.splat`, SuperSplat compressed PLY, Niantic `.spz` (read 2-4, write 3, 4),
///        glTF `.glb` with KHR_gaussian_splatting, and formats registered from above src/io
///        (OpenVDB point grids: vdb/VdbPoints.h). See docs/formats.md.
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
    std::string format;               ///< "ply-binary-le", "ply-binary-be", "ply-ascii", "splat", "ply-compressed", "spz-v2".."spz-v4", "glb", "vdb-points"
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

/// @brief The readers' rule for unusable Gaussians (NaN/Inf, values that overflow in use) applied
///        to a cloud built in memory (the Python module's Model.from_arrays()): refuse it, drop or
///        keep them as options say; `name` stands for the source in messages.
/// @throws InputError as readGaussians() does.
void applyReadRules(const std::string& name, GaussianCloud& cloud, const ReadOptions& options = {},
                    ReadReport* report = nullptr);

/// @brief readGaussians() of bytes already in memory (fuzzers, in-memory callers); `name` stands
///        for the file in messages.
GaussianCloud readGaussiansFromBytes(const std::string& name, const std::string& data, const ReadOptions& options = {},
                                     ReadReport* report = nullptr);

/// @brief Write graphdeco 3DGS PLY (binary little-endian, normals = 0, float32) atomically.
/// @throws InputError if the cloud holds NaN/Inf (a viewer would choke on it).
void writePly(const std::string& path, const GaussianCloud& cloud);

/// @brief Throws InputError for a model without Gaussians, or naming the first Gaussian and
///        graphdeco property that is NaN/Inf or unusable (readGaussians() refuses both: no command
///        writes a file that a reader refuses). Every writer calls it first.
void checkModelForWriting(const std::string& path, const GaussianCloud& cloud);

/// @brief The `.spz` bytes of a cloud, version 3 (gzip) or 4 (NGSP + zstd); `path` names it in messages.
/// @throws UsageError for another version; InputError for NaN/Inf or centres beyond the 24-bit range.
std::string encodeSpz(const std::string& path, const GaussianCloud& cloud, int version = 3);
/// @brief encodeSpz() written atomically.
void writeSpz(const std::string& path, const GaussianCloud& cloud, int version = 3);
/// @brief SuperSplat compressed PLY (chunks of 256 in Morton order, 11-10-11 bit centres and
///        scales, 8-bit colour and alpha, smallest-three rotation, uchar SH): what the reader reads.
void writeCompressedPly(const std::string& path, const GaussianCloud& cloud);
/// @brief antimatter15 `.splat` (32-byte records, SH degree 0 only: higher bands are dropped).
void writeSplat(const std::string& path, const GaussianCloud& cloud);
/// @brief The `.glb` bytes (glTF 2.0, KHR_gaussian_splatting, float32 attributes) of a cloud.
std::string encodeGlb(const std::string& path, const GaussianCloud& cloud);
/// @brief encodeGlb() written atomically.
void writeGlb(const std::string& path, const GaussianCloud& cloud);

/// @brief A model format whose code lives above src/io (src/io must not include OpenVDB): the
///        OpenVDB point grids of vdb/VdbPoints.h register themselves with registerModelFormat().
struct ModelFormatHooks {
    std::string name;      ///< as in ReadReport::format, e.g. "vdb-points"
    std::string extension; ///< written for paths ending so, e.g. ".vdb"
    bool (*detect)(const std::string& data) = nullptr;
    GaussianCloud (*read)(const std::string& name, const std::string& data, ReadReport& report) = nullptr;
    void (*write)(const std::string& path, const GaussianCloud& cloud) = nullptr;
};
/// @brief Make readGaussians() and writeGaussians() handle one more format (idempotent by name).
void registerModelFormat(const ModelFormatHooks& hooks);

/// @brief Options for writeGaussians().
struct WriteOptions {
    int spzVersion = 3; ///< 3 (gzip, read by every spz reader) or 4 (zstd)
};
/// @brief The format writeGaussians() picks for a path: "compressed-ply" (".compressed.ply"), "ply",
///        "splat", "spz", "glb" or a registered one; "" when the extension is not one we write.
std::string outputFormatOf(const std::string& path);
/// @brief Write a model in the format its extension names (outputFormatOf()).
/// @throws UsageError for an extension we do not write (the message lists those we do).
void writeGaussians(const std::string& path, const GaussianCloud& cloud, const WriteOptions& options = {});

/// @brief The graphdeco property names in file order for a given SH degree.
std::vector<std::string> graphdecoPropertyNames(int shDegree);

/// @brief Graphdeco name of SH coefficient j (0 = f_dc) of colour channel c for a degree:
///        f_dc_c, or f_rest_{c*K'+j-1} with K' = (degree+1)^2 - 1.
std::string shPropertyName(int shDegree, int j, int c);

} // namespace splatwarp
