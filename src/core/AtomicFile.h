#pragma once
/// @file AtomicFile.h
/// @brief Write-to-temporary-then-rename, so a failed job never leaves a half-written output.
#include <string>

namespace splatwarp {

/// @brief Owns a temporary path next to the destination. Write to tempPath(), then commit()
///        renames it into place; if commit() is never reached (an exception), the destructor
///        removes the temporary file.
class AtomicFile {
public:
    explicit AtomicFile(std::string finalPath);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    const std::string& tempPath() const { return mTemp; }
    const std::string& finalPath() const { return mFinal; }
    /// @brief Rename the temporary file onto the final path. Throws IoError on failure.
    void commit();

private:
    std::string mFinal, mTemp;
    bool mCommitted = false;
};

/// @brief Write a whole string atomically (reports, JSON).
void writeFileAtomic(const std::string& path, const std::string& contents);

} // namespace splatwarp
