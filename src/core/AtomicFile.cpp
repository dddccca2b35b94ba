#include "core/AtomicFile.h"

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sys/stat.h>
#include <unistd.h>

#include "core/Error.h"

namespace splatwarp {

namespace {

std::atomic<unsigned> gCounter{0};
OutputSet* gActive = nullptr;

// Paths a signal handler removes: files are unlinked, directories rmdir'ed (only when empty).
// Fixed-size lock-free slots, because a handler may only touch async-signal-safe state.
constexpr int kSlots = 4096;
std::atomic<char*> gSlot[kSlots];
std::atomic<bool> gSlotIsDir[kSlots];

int registerCleanup(const std::string& path, bool isDir)
{
    char* copy = strdup(path.c_str());
    for (int i = 0; i < kSlots; ++i) {
        char* expected = nullptr;
        if (!gSlot[i].compare_exchange_strong(expected, copy)) continue;
        gSlotIsDir[i].store(isDir); // until then a handler may try the wrong call: unlink/rmdir fail harmlessly
        return i;
    }
    std::free(copy); // more than kSlots pending outputs: this one is not cleaned up on a signal
    return -1;
}

void unregisterCleanup(int slot)
{
    if (slot >= 0) std::free(gSlot[slot].exchange(nullptr));
}

extern "C" void cleanupOnSignal(int sig)
{
    for (int i = 0; i < kSlots; ++i) {
        const char* p = gSlot[i].load();
        if (p && !gSlotIsDir[i].load()) ::unlink(p);
    }
    // Created directories, innermost first: repeat while some rmdir succeeds.
    for (bool progress = true; progress;) {
        progress = false;
        for (int i = 0; i < kSlots; ++i) {
            char* p = gSlot[i].load();
            if (p && gSlotIsDir[i].load() && ::rmdir(p) == 0) {
                gSlot[i].store(nullptr);
                progress = true;
            }
        }
    }
    std::signal(sig, SIG_DFL);
    std::raise(sig);
}

std::string tempPathFor(const std::string& finalPath)
{
    // Same directory as the destination so rename() is atomic (same filesystem); a short name so
    // that a destination name near NAME_MAX still has a valid temporary.
    const std::filesystem::path parent = std::filesystem::path(finalPath).parent_path();
    const std::string name = msg(".sw", ::getpid(), "-", gCounter++, ".tmp");
    return (parent / name).string();
}

} // namespace

void checkOutputPath(const std::string& path)
{
    if (path.empty()) throw IoError("empty output path");
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0) return; // does not exist yet: fine
    if (S_ISLNK(st.st_mode))
        throw IoError(msg(path, ": is a symbolic link; refusing to replace it (give the path it points to)"));
    if (S_ISDIR(st.st_mode)) throw IoError(msg(path, ": is a directory, expected a file path"));
    if (!S_ISREG(st.st_mode))
        throw IoError(msg(path, ": is not a regular file (a device, FIFO or socket); refusing to write to it"));
}

AtomicFile::AtomicFile(std::string finalPath) : mFinal(std::move(finalPath))
{
    checkOutputPath(mFinal);
    if (gActive) gActive->checkNotInput(mFinal);
    mTemp = tempPathFor(mFinal);
    mSlot = registerCleanup(mTemp, false);
}

AtomicFile::~AtomicFile()
{
    if (mCommitted) return;
    std::remove(mTemp.c_str());
    unregisterCleanup(mSlot);
}

void AtomicFile::commit()
{
    if (gActive) {
        gActive->stage(mTemp, mFinal, mSlot);
    } else {
        if (std::rename(mTemp.c_str(), mFinal.c_str()) != 0)
            throw IoError(msg(mFinal, ": cannot write: ", std::strerror(errno)));
        unregisterCleanup(mSlot);
    }
    mCommitted = true;
}

void writeFileAtomic(const std::string& path, const std::string& contents)
{
    AtomicFile file(path);
    {
        std::ofstream out(file.tempPath(), std::ios::binary);
        if (!out) throw IoError(msg(path, ": cannot open for writing: ", std::strerror(errno)));
        out << contents;
        out.close();
        if (!out) throw IoError(msg(path, ": write failed (disk full or file size limit?)"));
    }
    file.commit();
}

OutputSet::OutputSet(std::vector<std::string> inputs) : mInputs(std::move(inputs)), mPrevious(gActive)
{
    gActive = this;
}

OutputSet::~OutputSet()
{
    gActive = mPrevious;
    if (mCommitted) return;
    for (const Staged& s : mStaged) {
        std::remove(s.temp.c_str());
        unregisterCleanup(s.slot);
    }
    for (auto it = mCreatedDirs.rbegin(); it != mCreatedDirs.rend(); ++it) {
        std::error_code ec;
        std::filesystem::remove(it->first, ec); // only removes an empty directory
        unregisterCleanup(it->second);
    }
}

OutputSet* OutputSet::active() { return gActive; }

void OutputSet::createDirectory(const std::string& dir)
{
    if (dir.empty()) throw IoError("empty output directory path");
    checkNotInput(dir);
    std::vector<std::filesystem::path> missing;
    std::error_code ec;
    for (std::filesystem::path p = dir; !p.empty() && !std::filesystem::exists(p, ec); p = p.parent_path()) {
        missing.push_back(p);
        if (p == p.parent_path()) break;
    }
    std::filesystem::create_directories(dir, ec);
    if (ec) throw IoError(msg(dir, ": cannot create output directory: ", ec.message()));
    if (!std::filesystem::is_directory(dir, ec)) throw IoError(msg(dir, ": exists and is not a directory"));
    for (auto it = missing.rbegin(); it != missing.rend(); ++it)
        mCreatedDirs.emplace_back(it->string(), registerCleanup(it->string(), true));
}

void OutputSet::removeOnCommit(const std::string& path) { mStale.push_back(path); }

void OutputSet::checkNotInput(const std::string& path) const
{
    for (const std::string& in : mInputs) {
        std::error_code ec;
        if (!in.empty() && std::filesystem::equivalent(in, path, ec))
            throw IoError(msg(path, ": is also an input of this command (", in, "); refusing to overwrite it"));
    }
}

void OutputSet::checkTarget(const std::string& path) const
{
    checkOutputPath(path);
    checkNotInput(path);
}

void OutputSet::stage(const std::string& temp, const std::string& finalPath, int slot)
{
    mStaged.push_back({temp, finalPath, slot});
}

void OutputSet::commit()
{
    for (const std::string& stale : mStale) {
        std::error_code ec;
        if (std::filesystem::is_regular_file(std::filesystem::symlink_status(stale, ec))) std::filesystem::remove(stale, ec);
    }
    for (std::size_t i = 0; i < mStaged.size(); ++i) {
        if (std::rename(mStaged[i].temp.c_str(), mStaged[i].final.c_str()) != 0)
            throw IoError(msg(mStaged[i].final, ": cannot write: ", std::strerror(errno))); // destructor removes the rest
        unregisterCleanup(mStaged[i].slot);
        mStaged[i].slot = -1;
        mStaged[i].temp.clear();
    }
    for (const auto& dir : mCreatedDirs) unregisterCleanup(dir.second);
    mCommitted = true;
}

void installSignalCleanup()
{
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, cleanupOnSignal);
    std::signal(SIGXFSZ, SIG_IGN);
}

} // namespace splatwarp
