#include "job/ZipWriter.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "core/AtomicFile.h"
#include "core/Error.h"

namespace splatwarp {

namespace {

constexpr std::uint16_t kDosDate = (0 << 9) | (1 << 5) | 1; // 1980-01-01: the same bytes for the same files
constexpr std::uint16_t kUtf8Names = 1 << 11;

/// Little-endian bytes of a record.
struct Bytes {
    std::string b;
    Bytes& u16(std::uint32_t v) { return put(v, 2); }
    Bytes& u32(std::uint64_t v) { return put(v, 4); }
    Bytes& u64(std::uint64_t v) { return put(v, 8); }
    Bytes& put(std::uint64_t v, int n)
    {
        for (int i = 0; i < n; ++i) b.push_back(char((v >> (8 * i)) & 0xff));
        return *this;
    }
};

/// The archive file being written, with its offset.
class Archive {
public:
    Archive(const std::string& zipPath, const std::string& temp) : mPath(zipPath)
    {
        mFd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
        if (mFd < 0) fail(msg("cannot create: ", std::strerror(errno)));
    }
    ~Archive()
    {
        if (mFd >= 0) ::close(mFd);
    }
    std::uint64_t offset() const { return mOffset; }
    void write(const char* data, std::size_t n)
    {
        for (std::size_t done = 0; done < n;) {
            const ssize_t w = ::write(mFd, data + done, n - done);
            if (w < 0 && errno == EINTR) continue;
            if (w <= 0) fail(msg("write failed: ", std::strerror(errno), " (disk full or file size limit?)"));
            done += std::size_t(w);
        }
        mOffset += n;
    }
    void write(const Bytes& b) { write(b.b.data(), b.b.size()); }
    void patch32(std::uint64_t at, std::uint32_t v)
    {
        const Bytes b = Bytes().u32(v);
        if (::pwrite(mFd, b.b.data(), 4, off_t(at)) != 4) fail(msg("write failed: ", std::strerror(errno)));
    }
    void close()
    {
        const int fd = mFd;
        mFd = -1;
        if (::close(fd) != 0) fail(msg("write failed: ", std::strerror(errno)));
    }
    [[noreturn]] void fail(const std::string& what) const { throw IoError(msg(mPath, ": ", what)); }

private:
    std::string mPath;
    int mFd = -1;
    std::uint64_t mOffset = 0;
};

struct Written {
    std::string name;
    std::uint64_t bytes, offset;
    std::uint32_t crc;
};

/// Open a member for reading only when it is a regular file of its recorded size.
int openMember(const Archive& zip, const std::string& path, const ZipMember& m)
{
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0) zip.fail(msg("cannot read ", path, ": ", std::strerror(errno)));
    if (!S_ISREG(st.st_mode)) zip.fail(msg(path, " is not a regular file (a symlink, FIFO or device); refusing to zip it"));
    const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) zip.fail(msg("cannot read ", path, ": ", std::strerror(errno)));
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || std::uint64_t(st.st_size) != m.bytes) {
        ::close(fd);
        zip.fail(msg(path, " has ", st.st_size, " bytes where its manifest entry records ", m.bytes, "; refusing to zip it"));
    }
    return fd;
}

/// Stream exactly m.bytes of the member after its local header; returns its CRC-32. Closes fd.
std::uint32_t copyMember(Archive& zip, int fd, const std::string& path, const ZipMember& m)
{
    struct Closer {
        int fd;
        ~Closer() { ::close(fd); }
    } closer{fd};
    std::vector<char> buffer(1 << 20);
    uLong crc = crc32(0L, Z_NULL, 0);
    for (std::uint64_t left = m.bytes; left > 0;) {
        const ssize_t r = ::read(fd, buffer.data(), std::size_t(std::min<std::uint64_t>(left, buffer.size())));
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) zip.fail(msg(path, " ended ", left, " bytes before the size its manifest entry records"));
        crc = crc32(crc, reinterpret_cast<const Bytef*>(buffer.data()), uInt(r));
        zip.write(buffer.data(), std::size_t(r));
        left -= std::uint64_t(r);
    }
    return std::uint32_t(crc);
}

Bytes localHeader(const ZipMember& m, bool zip64)
{
    Bytes h;
    h.u32(0x04034b50).u16(zip64 ? 45 : 20).u16(kUtf8Names).u16(0).u16(0).u16(kDosDate).u32(0); // crc patched later
    h.u32(zip64 ? 0xffffffffu : m.bytes).u32(zip64 ? 0xffffffffu : m.bytes).u16(std::uint32_t(m.name.size())).u16(zip64 ? 20 : 0);
    h.b += m.name;
    if (zip64) h.u16(1).u16(16).u64(m.bytes).u64(m.bytes);
    return h;
}

Bytes centralHeader(const Written& w, std::uint64_t zip64Above)
{
    const bool bigSize = w.bytes > zip64Above, bigOffset = w.offset > zip64Above;
    Bytes extra;
    if (bigSize) extra.u64(w.bytes).u64(w.bytes);
    if (bigOffset) extra.u64(w.offset);
    Bytes h;
    h.u32(0x02014b50).u16(45 | (3 << 8)).u16(bigSize || bigOffset ? 45 : 20).u16(kUtf8Names).u16(0).u16(0).u16(kDosDate).u32(w.crc);
    h.u32(bigSize ? 0xffffffffu : w.bytes).u32(bigSize ? 0xffffffffu : w.bytes).u16(std::uint32_t(w.name.size()));
    h.u16(extra.b.empty() ? 0 : std::uint32_t(4 + extra.b.size())).u16(0).u16(0).u16(0).u32(0100644u << 16);
    h.u32(bigOffset ? 0xffffffffu : w.offset);
    h.b += w.name;
    if (!extra.b.empty()) h.u16(1).u16(std::uint32_t(extra.b.size())).b += extra.b;
    return h;
}

Bytes endRecords(std::uint64_t count, std::uint64_t cdOffset, std::uint64_t cdSize, std::uint64_t end, std::uint64_t zip64Above)
{
    const bool zip64 = count >= 0xffff || cdOffset > zip64Above || cdSize > zip64Above;
    Bytes e;
    if (zip64) {
        e.u32(0x06064b50).u64(44).u16(45 | (3 << 8)).u16(45).u32(0).u32(0).u64(count).u64(count).u64(cdSize).u64(cdOffset);
        e.u32(0x07064b50).u32(0).u64(end).u32(1);
    }
    const std::uint32_t n = zip64 ? 0xffff : std::uint32_t(count);
    e.u32(0x06054b50).u16(0).u16(0).u16(n).u16(n);
    e.u32(zip64 ? 0xffffffffu : cdSize).u32(zip64 ? 0xffffffffu : cdOffset).u16(0);
    return e;
}

} // namespace

void writeZip(const std::string& zipPath, const std::string& dir, const std::vector<ZipMember>& members, std::uint64_t zip64Above)
{
    AtomicFile file(zipPath);
    std::vector<Written> written;
    {
        Archive zip(zipPath, file.tempPath());
        for (const ZipMember& m : members) {
            if (m.name.empty() || m.name.size() > 0xffff) zip.fail(msg("member name of ", m.name.size(), " bytes"));
            const std::string path = (std::filesystem::path(dir) / m.name).string();
            const int fd = openMember(zip, path, m);
            const bool zip64 = m.bytes > zip64Above;
            written.push_back({m.name, m.bytes, zip.offset(), 0});
            zip.write(localHeader(m, zip64));
            written.back().crc = copyMember(zip, fd, path, m);
            zip.patch32(written.back().offset + 14, written.back().crc);
        }
        const std::uint64_t cdOffset = zip.offset();
        for (const Written& w : written) zip.write(centralHeader(w, zip64Above));
        zip.write(endRecords(written.size(), cdOffset, zip.offset() - cdOffset, zip.offset(), zip64Above));
        zip.close();
    }
    file.commit();
}

} // namespace splatwarp
