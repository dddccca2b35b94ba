#include "core/AtomicFile.h"

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <unistd.h>

#include "core/Error.h"

namespace splatwarp {

namespace {
std::atomic<unsigned> gCounter{0};
}

AtomicFile::AtomicFile(std::string finalPath) : mFinal(std::move(finalPath))
{
    // Same directory as the destination so rename() is atomic (same filesystem).
    mTemp = msg(mFinal, ".tmp-", ::getpid(), "-", gCounter++);
}

AtomicFile::~AtomicFile()
{
    if (!mCommitted) std::remove(mTemp.c_str());
}

void AtomicFile::commit()
{
    if (std::rename(mTemp.c_str(), mFinal.c_str()) != 0)
        throw IoError(msg(mFinal, ": cannot write: ", std::strerror(errno)));
    mCommitted = true;
}

void writeFileAtomic(const std::string& path, const std::string& contents)
{
    AtomicFile file(path);
    {
        std::ofstream out(file.tempPath(), std::ios::binary);
        if (!out) throw IoError(msg(path, ": cannot open for writing: ", std::strerror(errno)));
        out << contents;
        out.flush();
        if (!out) throw IoError(msg(path, ": write failed"));
    }
    file.commit();
}

} // namespace splatwarp
