#pragma once
/// @file SogFormat.h
/// @brief Pieces of the SOG reader and writer (internal to src/io): the zip container of a `.sog`
///        bundle, lossless WebP images, and the codebooks (256-entry scalar, k-means SH palette).
///        Layout after PlayCanvas splat-transform (src/lib/writers/write-sog.ts, readers/read-sog.ts).
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace splatwarp::sog {

/// WebP's largest width and height; also bounds the Gaussians one SOG can hold.
constexpr int kMaxWebpSide = 16383;
/// Centroids per row of shN_centroids.webp (each centroid takes shCoeffs texels of a row).
constexpr int kPaletteRow = 64;

/// @brief True when the data starts with a zip local file header ("PK\3\4").
bool hasZipMagic(const std::string& data);

/// @brief Stored (uncompressed) zip of the files in the given order, fixed dates: the same files give
///        the same bytes. WebP images do not deflate further.
std::string storedZip(const std::vector<std::pair<std::string, std::string>>& files);

/// @brief The central directory of a zip in memory: entry name -> where its data lies.
class ZipIndex {
public:
    /// @brief Index `data` (kept by reference: it must outlive the index).
    /// @throws InputError naming `path` when the archive is truncated or malformed, encrypted,
    ///         ZIP64, or holds an entry compressed other than stored/deflate.
    ZipIndex(const std::string& path, const std::string& data);
    bool contains(const std::string& name) const { return mEntries.count(name) != 0; }
    /// @brief The bytes of entry `name`, at most `maxBytes` of them once inflated (checked from the
    ///        directory before anything is inflated, and again while inflating); CRC-checked.
    /// @throws InputError when the entry is missing, too large, corrupt.
    std::string extract(const std::string& name, std::size_t maxBytes) const;

private:
    struct Entry {
        int method = 0;
        std::uint32_t crc = 0;
        std::uint64_t packed = 0, size = 0, offset = 0;
    };
    std::string mPath;        ///< for messages
    const std::string& mData; ///< the caller's bytes, which must outlive the index
    std::map<std::string, Entry> mEntries;
};

/// @brief RGBA8 pixels of an image, row-major.
struct Image {
    int width = 0, height = 0;
    std::vector<std::uint8_t> rgba;
};

/// @brief Lossless WebP of RGBA pixels (exact: RGB kept under alpha 0). @throws IoError.
std::string encodeWebp(const Image& image);
/// @brief Declared size of a WebP, read from its header without decoding.
/// @throws InputError naming `what` when it is not a WebP.
std::pair<int, int> webpSize(const std::string& what, const std::string& bytes);
/// @brief Decode a WebP into RGBA8. @throws InputError naming `what`.
Image decodeWebp(const std::string& what, const std::string& bytes);

/// @brief A 256-entry scalar codebook (ascending) and each value's nearest entry.
struct Codebook {
    std::vector<float> entries;
    std::vector<std::uint8_t> labels;
};
/// @brief 1-D k-means into 256 entries (Lloyd over the sorted values, started half at quantiles, half
///        spread over the range); labels follow the values' order. Deterministic; needs no seed.
Codebook quantize256(const std::vector<float>& values);

/// @brief The SH palette: k centroids of `dims` floats and each point's centroid.
struct Palette {
    std::size_t count = 0;
    std::vector<float> centroids; ///< [count, dims]
    std::vector<std::uint32_t> labels;
};
/// @brief k-means of n points of `dims` floats ([n, dims]) into at most k centroids, started from k
///        distinct points chosen with `seed`; `iterations` Lloyd rounds; the same input and seed
///        give the same palette on any machine and thread count. Up to 4096 centroids each label is
///        the nearest centroid; past that, the nearest in the 4 groups of centroids nearest the point.
Palette kmeans(const std::vector<float>& points, std::size_t n, int dims, std::size_t k, int iterations,
               std::uint64_t seed);

/// @brief splat-transform's palette size for n Gaussians, min(64, 2^floor(log2(n / 1024))) x 1024,
///        capped at `cap` (and at n).
std::size_t paletteSize(std::size_t n, std::size_t cap);

/// @brief Width and height of the per-Gaussian images for n Gaussians: width ceil(sqrt(n)/4)*4,
///        height ceil(n/width/4)*4 (multiples of 4, as splat-transform writes them).
std::pair<int, int> imageSize(std::size_t n);

} // namespace splatwarp::sog
