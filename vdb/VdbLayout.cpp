#include "vdb/VdbLayout.h"

#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <vector>

#include "core/Error.h"
#include "core/SafePath.h"
#include "core/Hash.h"

namespace splatwarp {

namespace {

constexpr std::int64_t kVdbMagic = 0x56444220;
constexpr std::uint32_t kFirstCheckedFormat = 222; ///< per-grid compression flags, instance parents

/// Little-endian fields read in order, each checked against the bytes left before `limit`.
class LayoutReader {
public:
    LayoutReader(std::istream& in, std::uint64_t size, const std::string& name)
        : mIn(in), mSize(size), mLimit(size), mName(name)
    {
    }

    std::uint64_t at() const { return mAt; }
    std::uint64_t left() const { return mLimit - mAt; }
    std::uint64_t limit() const { return mLimit; }
    void limitTo(std::uint64_t end) { mLimit = end; }

    template <typename T>
    T value(const std::string& what)
    {
        need(sizeof(T), what);
        char bytes[sizeof(T)];
        if (!mIn.read(bytes, sizeof(T))) fail(what, " cannot be read");
        mAt += sizeof(T);
        T v;
        std::memcpy(&v, bytes, sizeof(T));
        return v;
    }

    /// A length-prefixed string: its text when short (for messages), else skipped.
    std::string text(const std::string& what)
    {
        const std::uint32_t length = value<std::uint32_t>(what + "'s length");
        need(length, what);
        std::string s;
        if (length <= 256) {
            s.resize(length);
            if (length > 0 && !mIn.read(&s[0], length)) fail(what, " cannot be read");
            mAt += length;
        } else {
            seek(mAt + length);
        }
        return s;
    }

    void skip(std::uint64_t bytes, const std::string& what)
    {
        need(bytes, what);
        seek(mAt + bytes);
    }

    void seek(std::uint64_t to)
    {
        mAt = to;
        mIn.clear();
        if (!mIn.seekg(std::streamoff(to))) fail("byte ", to, " cannot be reached");
    }

    template <typename... Args>
    [[noreturn]] void fail(const Args&... args) const
    {
        throw InputError(msg(mName, ": ", args..., " (truncated or corrupt OpenVDB file?)"));
    }

private:
    void need(std::uint64_t bytes, const std::string& what) const
    {
        if (bytes > left())
            fail(what, " at byte ", mAt, " needs ", bytes, " bytes, ", left(), " are left of the ", mSize, "-byte file");
    }

    std::istream& mIn;
    std::uint64_t mSize, mLimit, mAt = 0;
    const std::string& mName;
};

/// One array of a delayed-load value, `count` elements of `size` bytes, stored in `bytes` bytes: raw
/// when 0, else Blosc-compressed, whose header (uncompressed size at bytes 4..7) sizes OpenVDB's
/// buffer. OpenVDB pads what it compresses (to at least 128 bytes): a little more is allowed.
void checkDelayedLoadArray(LayoutReader& r, std::uint32_t bytes, std::uint64_t count, std::uint64_t size,
                           const std::string& what)
{
    constexpr std::uint64_t kPadding = 4096;
    if (bytes == 0) {
        r.skip(count * size, what);
        return;
    }
    if (bytes < 16) r.fail(what, " is ", bytes, " bytes, less than a Blosc header");
    r.skip(4, what + " Blosc header");
    const std::uint32_t raw = r.value<std::uint32_t>(what + " uncompressed size");
    if (raw < count * size || raw > count * size + kPadding)
        r.fail(what, " holds ", raw, " bytes uncompressed for ", count, " leaves of ", size, " bytes");
    r.skip(bytes - 8, what);
}

/// OpenVDB's `file_delayed_load` value (type __delayedload): a leaf count, then a mask byte and a
/// compressed size (8 bytes) per leaf. OpenVDB sizes its arrays by the count and the Blosc headers,
/// not by the value's length: a flipped bit asked for gigabytes or failed an assertion.
void checkDelayedLoad(LayoutReader& r, std::uint32_t bytes, std::uint64_t maxLeaves, const std::string& what)
{
    if (bytes == 0) return;
    const std::uint64_t end = r.at() + bytes, limit = r.limit();
    if (bytes > r.left()) r.skip(bytes, what); // fails, naming the bytes left
    r.limitTo(end);
    const std::uint32_t count = r.value<std::uint32_t>(what + " leaf count");
    if (count > maxLeaves) r.fail(what, " counts ", count, " leaves, more than its grid's ", maxLeaves, " data bytes");
    checkDelayedLoadArray(r, r.value<std::uint32_t>(what + " masks' size"), count, 1, what + " masks");
    const std::uint32_t sizes = r.value<std::uint32_t>(what + " sizes' size");
    if (sizes != 0xffffffffu) checkDelayedLoadArray(r, sizes, count, 8, what + " sizes");
    r.limitTo(limit);
    r.seek(end);
}

/// A MetaMap: a count, then name, type name and a length-prefixed value per entry (OpenVDB reads a
/// typed value by its type and the rest by the length; each is at most what is left). `maxLeaves`
/// bounds a delayed-load value's leaf count (each leaf takes at least a byte of its grid's data).
void skipMetadata(LayoutReader& r, const std::string& whose, std::uint64_t maxLeaves)
{
    const std::uint32_t count = r.value<std::uint32_t>(whose + " metadata count");
    if (count > r.left() / 12) r.fail(whose, " metadata count ", count, " cannot fit in the ", r.left(), " bytes left");
    for (std::uint32_t m = 0; m < count; ++m) {
        const std::string name = r.text(whose + " metadata name");
        const std::string type = r.text(whose + " metadata '" + name + "' type");
        const std::uint32_t bytes = r.value<std::uint32_t>(whose + " metadata '" + name + "' size");
        if (type == "__delayedload") checkDelayedLoad(r, bytes, maxLeaves, whose + " metadata '" + name + "'");
        else r.skip(bytes, whose + " metadata '" + name + "' value");
    }
}

/// What OpenVDB reads of a grid for its metadata alone, before its voxel data: compression flags,
/// metadata and the transform's map name.
void checkGridHeader(LayoutReader& r, const std::string& which, std::uint64_t dataBytes)
{
    r.value<std::uint32_t>(which + " compression flags");
    skipMetadata(r, which, dataBytes);
    r.text(which + " transform");
}

/// A grid's offsets in its file: its start, its voxel data's start, its end.
struct GridOffsets {
    std::int64_t grid = 0, block = 0, end = 0;
};

/// Grid `index`'s descriptor: its name (returned), type name, instance parent and offsets.
std::string gridDescriptor(LayoutReader& r, std::int32_t index, GridOffsets& at)
{
    const std::string name = r.text("grid " + std::to_string(index) + " name");
    const std::string which = "grid '" + name + "'";
    r.text(which + " type");
    r.text(which + " instance parent");
    at.grid = r.value<std::int64_t>(which + " start");
    at.block = r.value<std::int64_t>(which + " data start");
    at.end = r.value<std::int64_t>(which + " end");
    return which;
}

/// A grid of a file with offsets: its descriptor, then its header at its start (before its data).
void checkGrid(LayoutReader& r, std::uint64_t size, std::int32_t index)
{
    GridOffsets at;
    const std::string which = gridDescriptor(r, index, at);
    if (!(std::int64_t(r.at()) <= at.grid && at.grid <= at.block && at.block <= at.end))
        r.fail(which, " has offsets out of order: start ", at.grid, ", data ", at.block, ", end ", at.end, " after byte ", r.at());
    if (std::uint64_t(at.end) > size) r.fail(which, " ends at byte ", at.end, " of a ", size, "-byte file");
    r.seek(std::uint64_t(at.grid));
    r.limitTo(std::uint64_t(at.block));
    checkGridHeader(r, which, std::uint64_t(at.end - at.block));
    r.limitTo(size);
    r.seek(std::uint64_t(at.end));
}

} // namespace

void checkVdbLayout(std::istream& in, std::uint64_t size, const std::string& name)
{
    LayoutReader r(in, size, name);
    if (size < 8 || r.value<std::int64_t>("magic") != kVdbMagic) return; // not ours to judge: OpenVDB refuses it
    const auto format = r.value<std::uint32_t>("format version");
    if (format < kFirstCheckedFormat) return;
    r.skip(8, "library version");
    const auto offsets = r.value<std::uint8_t>("grid offsets flag");
    r.skip(36, "UUID");
    skipMetadata(r, "file", size);
    const auto grids = r.value<std::int32_t>("grid count");
    if (grids < 0 || std::uint64_t(grids) > r.left() / 36)
        r.fail("grid count ", grids, " cannot fit in the ", r.left(), " bytes left");
    if (offsets != 0) {
        for (std::int32_t g = 0; g < grids; ++g) checkGrid(r, size, g);
    } else if (grids > 0) {
        // A stream (io::Stream): each grid's data follows its header unindexed; the first is checked.
        GridOffsets unused;
        checkGridHeader(r, gridDescriptor(r, 0, unused), size);
    }
}

void checkVdbFileLayout(const std::string& path)
{
    checkReadableFile(path, "volume"); // opening a FIFO hung from-vdb
    std::error_code ec;
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    std::ifstream in(path, std::ios::binary);
    if (ec || !in) throw IoError(msg(path, ": cannot open"));
    checkVdbLayout(in, std::uint64_t(size), path);
}

namespace {

constexpr std::size_t kUuidAt = 8 + 4 + 8 + 1; ///< after magic, format, library version, offsets flag
constexpr std::size_t kUuidSize = 36;

bool holdsUuid(const char* header, std::size_t size)
{
    std::int64_t magic = 0;
    if (size < kUuidAt + kUuidSize) return false;
    std::memcpy(&magic, header, sizeof magic);
    if (magic != kVdbMagic) return false;
    for (std::size_t i = 0; i < kUuidSize; ++i) {
        const char c = header[kUuidAt + i];
        const bool dash = i == 8 || i == 13 || i == 18 || i == 23;
        if (dash ? c != '-' : !std::isxdigit(static_cast<unsigned char>(c))) return false;
    }
    return true;
}

// Two 64-bit lanes over 8-byte words (a tail zero-padded), each word mixed by multiplication: a
// tag, not a defence against forgery.
class TagHash {
public:
    void add(const char* data, std::size_t n)
    {
        std::size_t i = 0;
        for (; mFill == 0 && i + 8 <= n; i += 8) { // whole words (little-endian, as OpenVDB's files)
            std::memcpy(&mWord, data + i, 8);
            flush();
        }
        for (; i < n; ++i) {
            mWord |= std::uint64_t(static_cast<unsigned char>(data[i])) << (8 * mFill);
            if (++mFill == 8) flush();
        }
        mLength += n;
    }
    std::string uuid()
    {
        if (mFill) flush();
        const std::uint64_t a = mix64(mA ^ mLength), b = mix64(mB + mLength);
        char text[kUuidSize + 1];
        std::snprintf(text, sizeof text, "%08x-%04x-8%03x-%04x-%012llx", unsigned(a >> 32), unsigned((a >> 16) & 0xffff),
                      unsigned(a & 0xfff), unsigned(0x8000 | ((b >> 48) & 0x3fff)),
                      static_cast<unsigned long long>(b & 0xffffffffffffull));
        return text;
    }

private:
    void flush()
    {
        mA = (mA ^ mWord) * 0x100000001b3ull;
        mB = ((mB ^ mWord) * 0x9e3779b97f4a7c15ull);
        mB = (mB << 29) | (mB >> 35);
        mWord = 0;
        mFill = 0;
    }
    std::uint64_t mA = 0xcbf29ce484222325ull, mB = 0x84222325cbf29ce4ull, mWord = 0, mLength = 0;
    int mFill = 0;
};

} // namespace

void settleVdbUuid(std::string& bytes)
{
    if (!holdsUuid(bytes.data(), bytes.size())) return;
    TagHash hash;
    hash.add(bytes.data(), kUuidAt);
    hash.add(bytes.data() + kUuidAt + kUuidSize, bytes.size() - kUuidAt - kUuidSize);
    bytes.replace(kUuidAt, kUuidSize, hash.uuid());
}

void settleVdbFileUuid(const std::string& path)
{
    std::fstream file(path, std::ios::binary | std::ios::in | std::ios::out);
    if (!file) throw IoError(msg(path, ": cannot open to settle its UUID"));
    std::vector<char> chunk(std::size_t(1) << 20);
    file.read(chunk.data(), std::streamsize(kUuidAt + kUuidSize));
    const std::size_t head = std::size_t(file.gcount());
    if (!holdsUuid(chunk.data(), head)) return;
    TagHash hash;
    hash.add(chunk.data(), kUuidAt);
    while (file.read(chunk.data(), std::streamsize(chunk.size())) || file.gcount() > 0)
        hash.add(chunk.data(), std::size_t(file.gcount()));
    file.clear();
    const std::string uuid = hash.uuid();
    file.seekp(std::streamoff(kUuidAt));
    file.write(uuid.data(), std::streamsize(uuid.size()));
    file.close();
    if (!file) throw IoError(msg(path, ": cannot rewrite its header (disk full?)"));
}

} // namespace splatwarp
