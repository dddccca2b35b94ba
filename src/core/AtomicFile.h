#pragma once
/// @file AtomicFile.h
/// @brief Write-to-temporary-then-rename, so a failed job never leaves a half-written output, and
///        OutputSet, so a command's outputs appear together or not at all.
#include <initializer_list>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace splatwarp {

/// @brief Owns a short temporary path next to the destination (".sw<pid>-<n>.tmp", so a
///        255-byte file name still fits). Write to tempPath(), then commit() renames it into place
///        (or hands it to the active OutputSet); if commit() is never reached (an exception, a
///        signal), the temporary file is removed.
/// @throws IoError from the constructor when the destination must not be written: empty path, a
///         directory, a symlink, a device/FIFO/socket, or (with an active OutputSet) one of the
///         command's inputs.
class AtomicFile {
public:
    explicit AtomicFile(std::string finalPath);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    const std::string& tempPath() const { return mTemp; }
    const std::string& finalPath() const { return mFinal; }
    /// @brief Rename the temporary file onto the final path, or defer that to the active
    ///        OutputSet. Throws IoError on failure.
    void commit();

private:
    std::string mFinal, mTemp;
    int mSlot = -1; ///< signal-cleanup registration
    bool mCommitted = false;
};

/// @brief The bytes of a whole file; `what` names it in messages ("camera file", "recipe", ...).
/// @throws IoError when it is a directory or not a regular file (a device, FIFO), cannot be opened or a read fails
std::string readWholeFile(const std::string& path, const std::string& what = "file");

/// @brief Write a whole string atomically (reports, JSON); checks flush and close.
void writeFileAtomic(const std::string& path, const std::string& contents);
/// @brief writeFileAtomic() of pieces written one after another (no concatenated copy).
void writeFileAtomic(const std::string& path, std::initializer_list<std::string_view> pieces);

/// @brief Throws IoError when path must not be replaced by a regular file (see AtomicFile).
void checkOutputPath(const std::string& path);

/// @brief Output folders a command creates: those it created are removed again (when empty)
///        unless keep() is called, also on SIGINT/SIGTERM/SIGHUP, so a failed command leaves no
///        empty folders behind.
class DirectoryGuard {
public:
    DirectoryGuard() = default;
    ~DirectoryGuard();
    DirectoryGuard(const DirectoryGuard&) = delete;
    DirectoryGuard& operator=(const DirectoryGuard&) = delete;
    /// @brief create_directories(dir), remembering what it created. @throws IoError.
    void create(const std::string& dir);
    /// @brief The command succeeded: leave the folders.
    void keep() { mKept = true; }

private:
    std::vector<std::pair<std::string, int>> mCreated; ///< outermost first, with cleanup slots
    bool mKept = false;
};

/// @brief One command's outputs, committed together. While it lives (one at a time per process),
///        AtomicFile::commit() only stages; commit() renames every staged file into place at the
///        end. Destroyed uncommitted (exception) it removes the staged files and the directories
///        it created; SIGINT/SIGTERM/SIGHUP do the same (installSignalCleanup()).
class OutputSet {
public:
    /// @param inputs files the command reads: an output that is the same file is refused.
    explicit OutputSet(std::vector<std::string> inputs = {});
    ~OutputSet();
    OutputSet(const OutputSet&) = delete;
    OutputSet& operator=(const OutputSet&) = delete;

    /// @brief The active set, or nullptr.
    static OutputSet* active();
    /// @brief create_directories(dir), remembering what it created (removed again on failure).
    void createDirectory(const std::string& dir);
    /// @brief One more file the command reads (readWholeFile() and the mesh reader add every file
    ///        they open): an output written after that is refused when it is this file. Thread-safe.
    void addInput(const std::string& path);
    /// @brief Remove this file at commit (a stale output of an earlier run that this run does not
    ///        write). @throws IoError when it is one of the inputs.
    void removeOnCommit(const std::string& path);
    /// @brief Rename every staged file into place; throws IoError (and rolls back the rest) on failure.
    void commit();

    /// @brief Refuse a destination that is one of the inputs (AtomicFile does; commands call
    ///        checkTarget() first to fail before any work).
    void checkNotInput(const std::string& path) const;
    /// @brief Before any work: checkOutputPath(), checkNotInput(), refuse a path that an
    ///        earlier checkTarget() of this command named already (two outputs on one file), and
    ///        create the output's folder when it is missing (removed again on failure).
    void checkTarget(const std::string& path);
    /// @brief For AtomicFile: refuse a second write of one path in one command (it would
    ///        silently replace the first output).
    void checkNotStaged(const std::string& path) const;
    /// @brief For AtomicFile: take over a written temporary file (and its cleanup slot).
    void stage(const std::string& temp, const std::string& finalPath, int slot);

private:
    void prepareFolderOf(const std::string& path);
    /// The input that `path` is (compared as files), "" when none.
    std::string inputAt(const std::string& path) const;

    struct Staged {
        std::string temp, final;
        int slot;
    };
    std::vector<std::string> mInputs, mStale;
    mutable std::mutex mInputsMutex; ///< addInput() may run on the threads that read
    std::vector<std::pair<std::string, std::string>> mClaimed; ///< checkTarget()ed outputs: place, as named
    std::vector<Staged> mStaged;
    std::unordered_map<std::string, std::string> mStagedPlaces; ///< place -> path as named
    DirectoryGuard mDirs;
    OutputSet* mPrevious = nullptr;
    bool mCommitted = false;
};

/// @brief Install the SIGINT/SIGTERM/SIGHUP handlers that remove registered temporaries and
///        created output directories before the process dies of the signal, and ignore SIGXFSZ so
///        a write past `ulimit -f` fails (and is reported) instead of killing the process.
void installSignalCleanup();

} // namespace splatwarp
