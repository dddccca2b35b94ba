#pragma once
/// @file SafePath.h
/// @brief Paths named by data that someone else may have written (a batch job list, a manifest):
///        they must stay inside the folder the user named, whatever they spell.
#include <initializer_list>
#include <string>

namespace splatwarp {

/// @brief root/rel when `rel` is a relative path with no ".." component and no component below
///        root that is a symbolic link (so it resolves inside root however the folder is laid
///        out); parts that do not exist yet are fine (they will be created as folders and files).
/// @throws InputError "WHAT: REASON" naming `what` (e.g. "jobs.json: job 3: \"output\" /etc/x").
std::string pathInside(const std::string& root, const std::string& rel, const std::string& what);

/// @brief Whether `path` is `dir` itself or lies below it, both resolved through symlinks of
///        their existing parts (lexically for the rest).
bool isWithin(const std::string& dir, const std::string& path);

/// @brief `path` absolute, resolved through symlinks of its existing parts and normalised, without
///        a trailing "/": what isWithin() compares (resolve many paths once, then compare them).
std::string resolvedPath(const std::string& path);

/// @brief isWithin() of two resolvedPath() results: a string comparison, no file-system call.
bool isWithinResolved(const std::string& dir, const std::string& path);

/// @brief Before a file is opened for reading: a folder, device, FIFO or socket is refused (opening
///        a FIFO blocks until a writer comes; /dev/zero never ends). A missing path is left to the
///        open, which names it. `what` names the file's role ("volume", "recipe").
/// @throws IoError "PATH: is a directory, not a WHAT" or "PATH: is not a regular file (...)".
void checkReadableFile(const std::string& path, const std::string& what);

/// @brief Before a command writes into `dir`'s subfolders `subs` (a relative path each): none is
///        a symbolic link (a planted one would take the files out of dir) or a file.
/// @throws IoError "DIR/SUB: is a symbolic link; WHO writes only inside its folder ...".
void checkSubfoldersAreFolders(const std::string& dir, std::initializer_list<const char*> subs, const std::string& who);

} // namespace splatwarp
