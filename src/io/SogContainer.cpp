/// The containers of SOG: the `.sog` zip bundle (splat-transform writes it stored, with data
/// descriptors, so sizes are taken from the central directory) and lossless WebP images.
/// Our own small zip code: job/ZipWriter archives files from disk and lives above src/io.
#include <webp/decode.h>
#include <webp/encode.h>
#include <zlib.h>

#include <algorithm>
#include <cstring>

#include "core/Error.h"
#include "io/SogFormat.h"

namespace splatwarp::sog {

namespace {

constexpr std::uint32_t kLocalSig = 0x04034b50, kCentralSig = 0x02014b50, kEndSig = 0x06054b50;
constexpr std::size_t kLocalBytes = 30, kCentralBytes = 46, kEndBytes = 22;
// Deflate cannot expand more than 1032:1 (RFC 1951 block limits, as the .spz reader uses).
constexpr std::uint64_t kMaxDeflateRatio = 1032;

std::uint64_t le(const std::string& d, std::size_t at, int n)
{
    std::uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | std::uint8_t(d[at + std::size_t(i)]);
    return v;
}

void put(std::string& s, std::uint64_t v, int n) // n <= 8
{
    for (int i = 0; i < n; ++i) s.push_back(char((v >> (8 * i)) & 0xff));
}

std::uint32_t crcOf(const std::string& s)
{
    return std::uint32_t(crc32(0L, reinterpret_cast<const Bytef*>(s.data()), uInt(s.size())));
}

// The fields local and central headers share: version 20, UTF-8 names, stored, 1980-01-01.
void commonFields(std::string& s, const std::string& name, const std::string& data)
{
    put(s, 20, 2);
    put(s, 1u << 11, 2);
    put(s, 0, 2);
    put(s, 0, 2);
    put(s, (1u << 5) | 1u, 2);
    put(s, crcOf(data), 4);
    put(s, data.size(), 4);
    put(s, data.size(), 4);
    put(s, name.size(), 2);
    put(s, 0, 2);
}

std::string inflateRaw(const std::string& path, const std::string& name, const char* src, std::size_t n,
                       std::size_t size)
{
    z_stream z{};
    if (inflateInit2(&z, -MAX_WBITS) != Z_OK) throw InputError(msg(path, ": ", name, ": cannot start inflate"));
    std::string out(size, '\0');
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(src));
    z.avail_in = uInt(n);
    z.next_out = reinterpret_cast<Bytef*>(out.empty() ? nullptr : &out[0]);
    z.avail_out = uInt(size);
    const int rc = inflate(&z, Z_FINISH);
    const std::size_t produced = size - z.avail_out;
    inflateEnd(&z);
    if (rc != Z_STREAM_END || produced != size)
        throw InputError(msg(path, ": ", name, ": deflate data is corrupt or does not inflate to the ", size,
                             " bytes the zip directory records"));
    return out;
}

} // namespace

bool hasZipMagic(const std::string& data) { return data.size() >= 4 && le(data, 0, 4) == kLocalSig; }

std::string storedZip(const std::vector<std::pair<std::string, std::string>>& files)
{
    std::string out, central;
    for (const auto& [name, data] : files) {
        if (out.size() + data.size() > 0xFFFFFFF0ull) throw IoError(msg(name, ": a .sog bundle over 4 GiB needs ZIP64"));
        put(central, kCentralSig, 4);
        put(central, 20, 2); // made by
        commonFields(central, name, data);
        put(central, 0, 6); // comment length, disk, internal attributes
        put(central, 0, 4); // external attributes
        put(central, out.size(), 4);
        central += name;
        put(out, kLocalSig, 4);
        commonFields(out, name, data);
        out += name;
        out += data;
    }
    const std::size_t at = out.size();
    out += central;
    put(out, kEndSig, 4);
    put(out, 0, 4);
    put(out, files.size(), 2);
    put(out, files.size(), 2);
    put(out, central.size(), 4);
    put(out, at, 4);
    put(out, 0, 2);
    return out;
}

ZipIndex::ZipIndex(const std::string& path, const std::string& data) : mPath(path), mData(data)
{
    if (data.size() < kEndBytes) throw InputError(msg(path, ": zip: ", data.size(), " bytes, too short for a zip"));
    std::size_t end = data.size() - kEndBytes; // the end record, before a comment of up to 64 KiB
    const std::size_t lowest = end > 0xFFFF ? end - 0xFFFF : 0;
    while (le(data, end, 4) != kEndSig) {
        if (end == lowest) throw InputError(msg(path, ": zip: no end of central directory (truncated?)"));
        --end;
    }
    const std::uint64_t count = le(data, end + 10, 2), dirBytes = le(data, end + 12, 4), dirAt = le(data, end + 16, 4);
    if (count == 0xFFFF || dirAt == 0xFFFFFFFF) throw InputError(msg(path, ": zip: ZIP64 archives are not supported"));
    if (dirAt + dirBytes > end) throw InputError(msg(path, ": zip: central directory lies outside the file (truncated?)"));
    std::size_t p = std::size_t(dirAt);
    for (std::uint64_t i = 0; i < count; ++i) {
        if (p + kCentralBytes > end || le(data, p, 4) != kCentralSig)
            throw InputError(msg(path, ": zip: central directory entry ", i, " is malformed"));
        Entry e;
        e.method = int(le(data, p + 10, 2));
        e.crc = std::uint32_t(le(data, p + 16, 4));
        e.packed = le(data, p + 20, 4);
        e.size = le(data, p + 24, 4);
        e.offset = le(data, p + 42, 4);
        const std::size_t nameLen = le(data, p + 28, 2), skip = le(data, p + 30, 2) + le(data, p + 32, 2);
        if (p + kCentralBytes + nameLen + skip > end) throw InputError(msg(path, ": zip: entry ", i, " overruns the directory"));
        const std::string name = data.substr(p + kCentralBytes, nameLen);
        if (le(data, p + 8, 2) & 1u) throw InputError(msg(path, ": zip: entry '", name, "' is encrypted"));
        if (e.method != 0 && e.method != 8)
            throw InputError(msg(path, ": zip: entry '", name, "' uses compression method ", e.method, " (read: stored, deflate)"));
        if (!mEntries.emplace(name, e).second) throw InputError(msg(path, ": zip: entry '", name, "' appears twice"));
        p += kCentralBytes + nameLen + skip;
    }
}

std::string ZipIndex::extract(const std::string& name, std::size_t maxBytes) const
{
    const auto it = mEntries.find(name);
    if (it == mEntries.end()) throw InputError(msg(mPath, ": the bundle has no entry '", name, "'"));
    const Entry& e = it->second;
    if (e.size > maxBytes)
        throw InputError(msg(mPath, ": ", name, ": ", e.size, " bytes uncompressed, more than the ", maxBytes,
                             " this SOG can need"));
    if (e.method == 0 ? e.packed != e.size : e.size > e.packed * kMaxDeflateRatio + 64)
        throw InputError(msg(mPath, ": ", name, ": the recorded sizes (", e.packed, " packed, ", e.size,
                             " unpacked) are impossible for its compression method"));
    if (e.offset + kLocalBytes > mData.size() || le(mData, std::size_t(e.offset), 4) != kLocalSig)
        throw InputError(msg(mPath, ": ", name, ": local header missing (truncated?)"));
    const std::uint64_t at = e.offset + kLocalBytes + le(mData, std::size_t(e.offset) + 26, 2) +
                             le(mData, std::size_t(e.offset) + 28, 2);
    if (at + e.packed > mData.size()) throw InputError(msg(mPath, ": ", name, ": data runs past the end (truncated?)"));
    std::string out = e.method == 0 ? mData.substr(std::size_t(at), std::size_t(e.size))
                                    : inflateRaw(mPath, name, mData.data() + at, std::size_t(e.packed), std::size_t(e.size));
    if (crcOf(out) != e.crc) throw InputError(msg(mPath, ": ", name, ": CRC mismatch (corrupt archive)"));
    return out;
}

// The advanced API for `exact`: the simple lossless call may rewrite the RGB of texels whose alpha
// is 0 (sh0 of a fully transparent Gaussian), losing its colour.
std::string encodeWebp(const Image& image)
{
    WebPConfig config;
    WebPPicture picture;
    if (!WebPConfigInit(&config) || !WebPPictureInit(&picture)) throw IoError("WebP: library version mismatch");
    config.lossless = 1; // the simple API's settings otherwise (quality 75, method 4)
    config.exact = 1;
    picture.use_argb = 1;
    picture.width = image.width;
    picture.height = image.height;
    WebPMemoryWriter writer;
    WebPMemoryWriterInit(&writer);
    picture.writer = WebPMemoryWrite;
    picture.custom_ptr = &writer;
    const bool ok = WebPPictureImportRGBA(&picture, image.rgba.data(), image.width * 4) && WebPEncode(&config, &picture);
    std::string bytes = ok ? std::string(reinterpret_cast<const char*>(writer.mem), writer.size) : std::string();
    WebPPictureFree(&picture);
    WebPMemoryWriterClear(&writer);
    if (!ok) throw IoError(msg("WebP encoding of a ", image.width, "x", image.height, " image failed"));
    return bytes;
}

std::pair<int, int> webpSize(const std::string& what, const std::string& bytes)
{
    int w = 0, h = 0;
    if (!WebPGetInfo(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size(), &w, &h))
        throw InputError(msg(what, ": not a WebP image (bad header or truncated)"));
    return {w, h};
}

Image decodeWebp(const std::string& what, const std::string& bytes)
{
    Image image;
    std::uint8_t* rgba =
        WebPDecodeRGBA(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size(), &image.width, &image.height);
    if (!rgba) throw InputError(msg(what, ": WebP image data is corrupt or truncated"));
    image.rgba.assign(rgba, rgba + std::size_t(image.width) * std::size_t(image.height) * 4);
    WebPFree(rgba);
    return image;
}

} // namespace splatwarp::sog
