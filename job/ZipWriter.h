#pragma once
/// @file ZipWriter.h
/// @brief A .zip of output files (`animate --zip`): stored (PLY floats barely deflate), ZIP64
///        where a size or offset needs it, written through core/AtomicFile so that an archive is
///        complete or absent, and its temporary is removed on every exit path, signals included.
///        Our own writer rather than libzip's: libzip's zip_close() writes a temporary of its own
///        naming that a SIGTERM leaves behind, and opens members by path (following symlinks,
///        blocking on a FIFO, reading a growing file without end).
#include <cstdint>
#include <string>
#include <vector>

namespace splatwarp {

/// @brief One member: a path relative to the folder (also its name in the archive) and the size
///        its manifest entry records.
struct ZipMember {
    std::string name;
    std::uint64_t bytes = 0;
};

/// @brief Write `members` (files under `dir`) into zipPath. Only regular files are read (a
///        symlink, FIFO or device is refused without being opened for reading), each exactly
///        its recorded size: a file that is larger or smaller than its manifest says is refused.
/// @param zip64Above members and offsets above this many bytes get ZIP64 records (tests lower it).
/// @throws IoError naming the archive and the member on any failure; nothing is left behind.
void writeZip(const std::string& zipPath, const std::string& dir, const std::vector<ZipMember>& members,
              std::uint64_t zip64Above = 0xFFFFFFFEull);

} // namespace splatwarp
