#include "core/AtomicFile.h"

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <sys/stat.h>
#include <unistd.h>

#include "core/Error.h"
#include "core/SafePath.h"

namespace splatwarp {

namespace {

std::atomic<unsigned> gCounter{0};
OutputSet* gActive = nullptr;

// Paths a signal handler removes: files are unlinked, directories rmdir'ed (only when empty).
// Lock-free slots in chunks allocated on demand (a 6,000-view render holds 6,000 temporaries),
// because a handler may only touch async-signal-safe state: it reads the chunk pointers, never
// allocates.
constexpr int kChunkSlots = 4096, kChunks = 1024; // up to 4 M pending paths
struct Slot {
    std::atomic<char*> path{nullptr};
    std::atomic<bool> isDir{false};
};
std::atomic<Slot*> gChunk[kChunks];
std::mutex gChunkMutex;

Slot* chunk(int c)
{
    Slot* s = gChunk[c].load();
    if (s) return s;
    std::lock_guard<std::mutex> lock(gChunkMutex);
    if (!(s = gChunk[c].load())) gChunk[c].store(s = new Slot[kChunkSlots]); // lives as long as the process
    return s;
}

std::atomic<int> gFreeHint{0}; // slots below it were taken when it was set: searches start there

int registerCleanup(const std::string& path, bool isDir)
{
    char* copy = strdup(path.c_str());
    const int start = gFreeHint.load();
    for (int n = 0; n < kChunks * kChunkSlots; ++n) {
        const int slot = (start + n) % (kChunks * kChunkSlots);
        Slot& s = chunk(slot / kChunkSlots)[slot % kChunkSlots];
        char* expected = nullptr;
        if (!s.path.compare_exchange_strong(expected, copy)) continue;
        s.isDir.store(isDir); // until then a handler may try the wrong call: unlink/rmdir fail harmlessly
        gFreeHint.store(slot + 1);
        return slot;
    }
    std::free(copy);
    throw IoError(msg(path, ": more than ", kChunks * kChunkSlots, " outputs pending at once; refusing to write one that a signal could not clean up"));
}

void unregisterCleanup(int slot)
{
    if (slot < 0) return;
    std::free(gChunk[slot / kChunkSlots].load()[slot % kChunkSlots].path.exchange(nullptr));
    if (slot < gFreeHint.load()) gFreeHint.store(slot);
}

/// Every registered slot (files or directories) for the handler.
template <typename F>
void forEachSlot(F&& f)
{
    for (int c = 0; c < kChunks; ++c)
        if (Slot* slots = gChunk[c].load())
            for (int i = 0; i < kChunkSlots; ++i) f(slots[i]);
}

extern "C" void cleanupOnSignal(int sig)
{
    forEachSlot([](Slot& s) {
        const char* p = s.path.load();
        if (p && !s.isDir.load()) ::unlink(p);
    });
    // Created directories, innermost first: repeat while some rmdir succeeds.
    for (bool progress = true; progress;) {
        progress = false;
        forEachSlot([&](Slot& s) {
            char* p = s.path.load();
            if (p && s.isDir.load() && ::rmdir(p) == 0) {
                s.path.store(nullptr);
                progress = true;
            }
        });
    }
    std::signal(sig, SIG_DFL);
    std::raise(sig);
}

/// One spelling per place, for comparing outputs that may not exist yet.
std::string placeOf(const std::string& path)
{
    std::error_code ec;
    return std::filesystem::weakly_canonical(std::filesystem::absolute(path, ec), ec).lexically_normal().string();
}

std::string tempPathFor(const std::string& finalPath)
{
    // Same directory as the destination so rename() is atomic (same filesystem); a short name so
    // that a destination name near NAME_MAX still has a valid temporary. The name is guessable
    // (pid, counter), so it is claimed with O_EXCL | O_NOFOLLOW: a symlink or FIFO planted under it
    // is passed over, never written through or blocked on.
    const std::filesystem::path parent = std::filesystem::path(finalPath).parent_path();
    for (int taken = 0; taken < 100000; ++taken) {
        const std::string path = (parent / msg(".sw", ::getpid(), "-", gCounter++, ".tmp")).string();
        const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
        if (fd >= 0) {
            ::close(fd);
            return path;
        }
        if (errno != EEXIST) return path; // the folder's own problem: the writer's open names it
    }
    throw IoError(msg(finalPath, ": no free temporary name beside it (100000 taken)"));
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
    if (gActive) gActive->checkNotInput(mFinal), gActive->checkNotStaged(mFinal);
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

std::string readWholeFile(const std::string& path, const std::string& what)
{
    checkReadableFile(path, what); // /dev/zero would be read until memory ran out
    if (gActive) gActive->addInput(path); // no output of this command may replace it
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(msg(path, ": cannot open ", what, ": ", std::strerror(errno)));
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw IoError(msg(path, ": cannot read ", what));
    return ss.str();
}

void writeFileAtomic(const std::string& path, const std::string& contents) { writeFileAtomic(path, {std::string_view(contents)}); }

void writeFileAtomic(const std::string& path, std::initializer_list<std::string_view> pieces)
{
    AtomicFile file(path);
    {
        std::ofstream out(file.tempPath(), std::ios::binary);
        if (!out) throw IoError(msg(path, ": cannot open for writing: ", std::strerror(errno)));
        for (const std::string_view piece : pieces) out.write(piece.data(), std::streamsize(piece.size()));
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
}

OutputSet* OutputSet::active() { return gActive; }

void OutputSet::createDirectory(const std::string& dir)
{
    checkNotInput(dir);
    mDirs.create(dir);
}

DirectoryGuard::~DirectoryGuard()
{
    for (auto it = mCreated.rbegin(); it != mCreated.rend(); ++it) {
        if (!mKept) {
            std::error_code ec;
            std::filesystem::remove(it->first, ec); // only removes an empty directory
        }
        unregisterCleanup(it->second);
    }
}

void DirectoryGuard::create(const std::string& dir)
{
    if (dir.empty()) throw IoError("empty output directory path");
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
        mCreated.emplace_back(it->string(), registerCleanup(it->string(), true));
}

void OutputSet::addInput(const std::string& path)
{
    const std::lock_guard<std::mutex> lock(mInputsMutex);
    mInputs.push_back(path);
}

std::string OutputSet::inputAt(const std::string& path) const
{
    const std::lock_guard<std::mutex> lock(mInputsMutex);
    for (const std::string& in : mInputs) {
        std::error_code ec;
        if (!in.empty() && std::filesystem::equivalent(in, path, ec)) return in;
    }
    return "";
}

void OutputSet::removeOnCommit(const std::string& path)
{
    if (const std::string in = inputAt(path); !in.empty())
        throw IoError(msg(path, ": is an input of this command (", in, "), and this run would remove it as an earlier run's "
                            "result; move it out of the output folder"));
    mStale.push_back(path);
}

void OutputSet::checkNotInput(const std::string& path) const
{
    if (const std::string in = inputAt(path); !in.empty())
        throw IoError(msg(path, ": is also an input of this command (", in, "); refusing to overwrite it"));
}

void OutputSet::checkTarget(const std::string& path)
{
    checkOutputPath(path);
    checkNotInput(path);
    prepareFolderOf(path); // first, so that the place below is spelled through the folder as it will be
    const std::string place = placeOf(path);
    for (const auto& [claimed, named] : mClaimed)
        if (claimed == place)
            throw IoError(msg(path, ": is also another output of this command (", named, "); give each output its own path"));
    mClaimed.emplace_back(place, path);
}

/// The folder an output goes into exists and takes files before any work: a missing one is
/// created now (and removed again when the command fails), as deform's output folder is, so an
/// hour of training never ends in "cannot open for writing".
void OutputSet::prepareFolderOf(const std::string& path)
{
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    const std::string folder = parent.empty() ? std::string(".") : parent.string();
    std::error_code ec;
    if (!std::filesystem::exists(folder, ec)) createDirectory(folder);
    if (!std::filesystem::is_directory(folder, ec)) throw IoError(msg(path, ": ", folder, " is not a directory"));
    if (::access(folder.c_str(), W_OK | X_OK) != 0)
        throw IoError(msg(path, ": cannot write into ", folder, ": ", std::strerror(errno)));
}

void OutputSet::checkNotStaged(const std::string& path) const
{
    const auto it = mStagedPlaces.find(placeOf(path));
    if (it != mStagedPlaces.end())
        throw IoError(msg(path, ": this command already wrote it as another output (", it->second, "); give each output its own path"));
}

void OutputSet::stage(const std::string& temp, const std::string& finalPath, int slot)
{
    mStaged.push_back({temp, finalPath, slot});
    mStagedPlaces.emplace(placeOf(finalPath), finalPath);
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
    mDirs.keep();
    mCommitted = true;
}

void installSignalCleanup()
{
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, cleanupOnSignal);
    std::signal(SIGXFSZ, SIG_IGN);
}

} // namespace splatwarp
