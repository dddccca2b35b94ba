#pragma once
/// @file ZipWriter.h
/// @brief A .zip of output files (`animate --zip`), through Debian's libzip: ZIP64 for archives
///        over 4 GiB (a long sequence of large PLYs), and zip_close() writes a temporary file
///        and renames it, so an archive is complete or absent.
#include <string>
#include <vector>

namespace splatwarp {

/// @brief Write `files` (paths relative to `dir`, stored under those names, uncompressed: PLY
///        floats barely deflate) into zipPath. @throws IoError naming the file on any failure.
void writeZip(const std::string& zipPath, const std::string& dir, const std::vector<std::string>& files);

} // namespace splatwarp
