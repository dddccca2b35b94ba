#pragma once
/// @file VdbLayout.h
/// @brief The byte layout of an OpenVDB file checked before OpenVDB reads it: the header, the file's
///        metadata, each grid's descriptor and the metadata and transform name at the start of each
///        grid, every length and offset against the bytes the file has. OpenVDB trusts them: on a
///        file cut short its stream fails at the last grid's end and every later read returns
///        garbage, so a string length of up to 4 GiB is allocated (an 832 KB volume cut by one byte:
///        6.7 GB and 15 s before "KeyError: Map"). Needs no OpenVDB header.
#include <cstdint>
#include <istream>
#include <string>

namespace splatwarp {

/// @brief Check the layout of the OpenVDB file `size` bytes long that `in` reads; `name` names it
///        in errors. Files of format 222 (OpenVDB 3, 2015) and later: with grid offsets (io::File
///        writes them) every grid, in a stream without them (io::Stream) the first grid's header,
///        whose data follows unindexed; another magic or an older format is left to OpenVDB.
/// @throws InputError naming the file, what was read where, and how many bytes it needed
void checkVdbLayout(std::istream& in, std::uint64_t size, const std::string& name);

/// @brief checkVdbLayout() of the file at `path`.
/// @throws IoError when it cannot be opened, InputError as checkVdbLayout()
void checkVdbFileLayout(const std::string& path);

/// @brief Replace the random UUID OpenVDB writes into a file's header (a fresh one each write, so
///        the same grids never gave the same bytes) with one derived from the rest of the file: 128
///        bits of a word-wise hash, as an RFC 9562 version-8 UUID. Equal files get equal tags, and
///        different files different ones (OpenVDB's delayed loading and Houdini tell files apart
///        by it). Bytes that do not start with a VDB header and a 36-character UUID are left as
///        they are.
void settleVdbUuid(std::string& bytes);

/// @brief settleVdbUuid() of a file written in place (read once; the header rewritten).
/// @throws IoError when the file cannot be read or rewritten
void settleVdbFileUuid(const std::string& path);

} // namespace splatwarp
