#include "core/SafePath.h"

#include <filesystem>
#include <sys/stat.h>

#include "core/Error.h"

namespace splatwarp {

namespace fs = std::filesystem;

std::string pathInside(const std::string& root, const std::string& rel, const std::string& what)
{
    const fs::path p(rel);
    if (rel.empty()) throw InputError(msg(what, ": empty path"));
    if (p.is_absolute() || p.has_root_name())
        throw InputError(msg(what, ": is an absolute path; it must be relative to the output folder ", root));
    for (const fs::path& part : p)
        if (part == "..") throw InputError(msg(what, ": climbs out of the output folder ", root, " (\"..\")"));
    fs::path at(root);
    bool below = true; // every part so far exists: the next may be a symlink
    for (const fs::path& part : p) {
        if (part.empty() || part == ".") continue;
        at /= part;
        struct stat st {};
        if (!below || ::lstat(at.c_str(), &st) != 0) { // not there yet: created below root, as are the parts after it
            below = false;
            continue;
        }
        if (S_ISLNK(st.st_mode))
            throw InputError(msg(what, ": ", at.string(), " is a symbolic link; a path inside the output folder may not follow one"));
    }
    if (at == fs::path(root)) throw InputError(msg(what, ": names the output folder itself"));
    return at.string();
}

void checkSubfoldersAreFolders(const std::string& dir, std::initializer_list<const char*> subs, const std::string& who)
{
    for (const char* sub : subs) {
        const fs::path p = fs::path(dir) / sub;
        std::error_code ec;
        const fs::file_status st = fs::symlink_status(p, ec);
        if (fs::is_symlink(st))
            throw IoError(msg(p.string(), ": is a symbolic link; ", who, " writes only inside its folder (remove the link)"));
        if (fs::exists(st) && !fs::is_directory(st)) throw IoError(msg(p.string(), ": exists and is not a directory"));
    }
}

std::string resolvedPath(const std::string& path)
{
    std::error_code ec;
    std::string s = fs::weakly_canonical(fs::absolute(path, ec), ec).lexically_normal().string();
    while (s.size() > 1 && s.back() == '/') s.pop_back(); // "a/b/" is a/b
    return s;
}

bool isWithinResolved(const std::string& dir, const std::string& path)
{
    if (path.compare(0, dir.size(), dir) != 0) return false;
    return path.size() == dir.size() || dir == "/" || path[dir.size()] == '/';
}

bool isWithin(const std::string& dir, const std::string& path) { return isWithinResolved(resolvedPath(dir), resolvedPath(path)); }

void checkReadableFile(const std::string& path, const std::string& what)
{
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (std::filesystem::is_directory(st)) throw IoError(msg(path, ": is a directory, not a ", what));
    if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
        throw IoError(msg(path, ": is not a regular file (a device, FIFO or socket); cannot read it as a ", what));
}

} // namespace splatwarp
