#pragma once
/// @file Sequence.h
/// @brief The run shared by `animate` and `batch`: numbered items (frames, jobs), this shard's
///        share of them, resume (an item whose files exist and match its manifest entry is not
///        redone), failures recorded while the others go on, one progress line per item with an
///        ETA, and a manifest rewritten atomically after every item; per-shard manifests merged.
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "job/Shard.h"

namespace splatwarp {

/// @brief What a sequence runs over and where it records it.
struct SequenceRun {
    std::string dir;              ///< output folder; file paths in the manifest are relative to it
    std::string itemName = "frame";
    nlohmann::json header;        ///< written at the top of the manifest (tool, input, spec hash ...)
    std::string settingsHash;     ///< entries written under another hash are never reused
    Shard shard;
    std::vector<int> items;       ///< every item of the run, in order; this shard takes its share
    /// This shard's items, when not those with item mod N = I (animate --warm-start: contiguous ranges).
    std::function<bool(int item)> owns;
    /// Whether a file (relative to dir) may belong to an item; resume never reuses an entry
    /// listing another (a frame's own numbered files, a job's files under its output).
    std::function<bool(int item, const std::string& rel)> fileBelongs;
    /// A digest of what an item reads (inputsDigest() of its files), taken just before it runs
    /// and kept in its entry as "inputs"; resume redoes an item whose digest differs (unset: none).
    std::function<std::string(int item)> inputsOf;
};

/// @brief Runs one item; returns its entry: "files" (paths relative to dir, written atomically)
///        plus anything to record (errors, timings). Throws to mark the item failed.
using ItemRunner = std::function<nlohmann::json(int item)>;
/// @brief The middle of an item's progress line, from its entry (e.g. the field errors).
using ItemSummary = std::function<std::string(const nlohmann::json& entry)>;

struct SequenceResult {
    int done = 0, resumed = 0, failed = 0;
    std::string manifest;         ///< path of the manifest written
    nlohmann::json entries;       ///< its entries, by item
};

/// @brief "manifest.json" for a whole run, "manifest.shard-I.json" for shard I.
std::string manifestName(const Shard& shard);

/// @brief Run this shard's items (see the file comment); the manifest lists every one of them.
///        A run holds a lock (flock on DIR/.MANIFEST.lock) on its manifest from start to end.
/// @throws InputError when another run holds that lock (it would lose the other's entries).
SequenceResult runSequence(const SequenceRun& run, const ItemRunner& runItem, const ItemSummary& summary);

/// @brief Why a finished entry's files cannot be trusted, or "" when every one verifies: a path
///        inside dir (relative, no "..", no symlink), a regular file of the recorded size and
///        digest, that `fileBelongs` (when set) gives to the entry's item.
std::string unverifiedFiles(const std::string& dir, const nlohmann::json& entry, const std::string& itemName,
                            const std::function<bool(int, const std::string&)>& fileBelongs = nullptr);

/// @brief Check a manifest's shape (what resume and merge read): header fields, items, shard,
///        entries with their item, status and files. @throws InputError naming `path`.
void checkManifest(const nlohmann::json& manifest, const std::string& path);
/// @brief JSON parse and checkManifest(). @throws InputError naming `path`.
nlohmann::json parseManifest(const std::string& text, const std::string& path);

/// @brief Join dir/manifest.shard-*.json into dir/manifest.json with "missing" and "failed" item
///        lists (items of the run that no shard finished, or that failed) and "shards" found.
///        Every "done" entry is verified (unverifiedFiles(); no file listed by two items): one
///        that fails counts as failed, its message says why. A manifest.json already there with
///        the shards' settings (a whole run, an earlier merge) fills the items no shard lists, its
///        items included, so a merge never loses its done entries. Holds manifest.json's lock (see runSequence()).
/// @throws InputError when there is no shard manifest, one is malformed, or they disagree on
///         the settings hash, the items or the shard count.
nlohmann::json mergeManifests(const std::string& dir, const std::function<bool(int, const std::string&)>& fileBelongs = nullptr);

/// @brief The first of dir's shard manifests, checked against the others as mergeManifests()
///        checks them (batch --merge reads which job list they ran). @throws InputError as it.
nlohmann::json readShardManifest(const std::string& dir);

/// @brief The messages of a merge's failed items (the first five), one indented line each.
std::string mergeFailures(const nlohmann::json& merged);


/// @brief 64-bit FNV-1a of bytes, as 16 hex digits (spec and settings hashes, file digests).
std::string fnv1a64(const std::string& bytes);
/// @brief fnv1a64() of a file's contents, read in one streaming pass. @throws IoError when unreadable.
std::string fileDigest(const std::string& path);
/// @brief One digest of the contents of files an item reads (in order; "" entries are skipped),
///        whatever their paths spell: a missing file or a folder counts as such, not as an error.
std::string inputsDigest(const std::vector<std::string>& paths);

/// @brief Whether a file name is the lock a run holds on a manifest of its folder (".NAME.lock"):
///        not an output.
bool isManifestLock(const std::string& fileName);

} // namespace splatwarp
