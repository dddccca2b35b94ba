#include "job/Sequence.h"

#include <algorithm>
#include <cstdint>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <map>
#include <optional>
#include <set>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "core/SafePath.h"
#include "io/JsonText.h"

namespace splatwarp {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

json readManifest(const fs::path& path) { return parseManifest(readWholeFile(path.string(), "manifest"), path.string()); }

/// Files of an entry with their sizes and digests (paths relative to dir).
json describeFiles(const std::string& dir, const json& files)
{
    json out = json::array();
    for (const json& f : files) {
        const std::string rel = f.get<std::string>();
        const std::string path = (fs::path(dir) / rel).string();
        out.push_back({{"path", rel}, {"bytes", fs::file_size(path)}, {"fnv1a64", fileDigest(path)}});
    }
    return out;
}

bool isWholeNumber(const json& v) { return v.is_number_integer() || v.is_number_unsigned(); }
/// Frame and job numbers: whole, 0 .. 10^7 (what int holds and a run can list).
bool isItemNumber(const json& v) { return isWholeNumber(v) && v.get<long long>() >= 0 && v.get<long long>() <= 10000000; }

/// Finished entries of earlier runs with the same settings, by item (any manifest in dir); an
/// entry whose files do not verify is computed again, never followed.
std::map<int, json> finishedEntries(const SequenceRun& run)
{
    std::map<int, json> out;
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(run.dir, ec)) {
        const std::string name = e.path().filename().string();
        if (name.rfind("manifest", 0) != 0 || e.path().extension() != ".json" || !e.is_regular_file(ec) || e.is_symlink(ec)) continue;
        json m;
        try {
            m = readManifest(e.path());
        } catch (const Error&) {
            continue; // an unreadable manifest only costs redoing its items
        }
        if (m["settingsHash"] != run.settingsHash || m["itemName"] != run.itemName) continue;
        for (const json& entry : m["entries"])
            if (entry["status"] == "done" && unverifiedFiles(run.dir, entry, run.itemName, run.fileBelongs).empty())
                out[entry[run.itemName].get<int>()] = entry;
    }
    return out;
}

void writeManifest(const SequenceRun& run, const std::string& path, const std::map<int, json>& entries,
                   const std::set<int>& items)
{
    json m = run.header;
    m["settingsHash"] = run.settingsHash;
    m["itemName"] = run.itemName;
    m["items"] = items;
    m["shard"] = {{"index", run.shard.index}, {"count", run.shard.count}, {"source", run.shard.source}};
    m["entries"] = json::array();
    for (const auto& [item, entry] : entries) m["entries"].push_back(entry);
    writeFileAtomic(path, m.dump(2) + "\n");
}

/// An exclusive flock on DIR/.NAME.lock for a manifest DIR/NAME while alive: two runs writing one
/// manifest would each rewrite it without the other's entries. The kernel drops it with the process.
class ManifestLock {
public:
    explicit ManifestLock(const std::string& manifest)
    {
        const fs::path m(manifest);
        const std::string path = (m.parent_path() / ("." + m.filename().string() + ".lock")).string();
        mFd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
        if (mFd < 0) throw IoError(msg(path, ": cannot open the lock of ", manifest, ": ", std::strerror(errno)));
        if (::flock(mFd, LOCK_EX | LOCK_NB) != 0) {
            const int err = errno;
            ::close(mFd);
            if (err == EWOULDBLOCK)
                throw InputError(msg(manifest, ": another run is writing it now (", path,
                                     " is locked); wait for that run, or give this one another -o or --shard"));
            throw IoError(msg(path, ": cannot lock: ", std::strerror(err)));
        }
    }
    ~ManifestLock() { ::close(mFd); }
    ManifestLock(const ManifestLock&) = delete;
    ManifestLock& operator=(const ManifestLock&) = delete;

private:
    int mFd = -1;
};

/// One item, with progress lines of the stages below silenced (one line per item instead).
json runOne(const SequenceRun& run, int item, const ItemRunner& runItem)
{
    const Stopwatch clock;
    const bool talk = progressEnabled();
    setProgressEnabled(false);
    json entry;
    try {
        entry = runItem(item);
        entry["files"] = describeFiles(run.dir, entry.value("files", json::array()));
        entry["status"] = "done";
    } catch (const std::exception& e) {
        entry = {{"status", "failed"}, {"message", e.what()}};
    }
    setProgressEnabled(talk);
    entry[run.itemName] = item;
    entry["ms"] = clock.ms();
    return entry;
}

} // namespace

namespace {

constexpr std::uint64_t kFnvOffset = 1469598103934665603ull;

std::uint64_t fnvAdd(std::uint64_t h, const char* bytes, std::size_t n)
{
    for (std::size_t i = 0; i < n; ++i) h = (h ^ static_cast<unsigned char>(bytes[i])) * 1099511628211ull;
    return h;
}

std::string hex16(std::uint64_t h)
{
    char out[17];
    std::snprintf(out, sizeof out, "%016llx", static_cast<unsigned long long>(h));
    return out;
}

} // namespace

std::string fnv1a64(const std::string& bytes) { return hex16(fnvAdd(kFnvOffset, bytes.data(), bytes.size())); }

std::string fileDigest(const std::string& path)
{
    checkReadableFile(path, "file to digest");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(msg(path, ": cannot open: ", std::strerror(errno)));
    std::vector<char> buffer(1 << 20); // models can be 100s of MB: one pass, not the whole file in memory
    std::uint64_t h = kFnvOffset;
    while (in.read(buffer.data(), std::streamsize(buffer.size())) || in.gcount() > 0) h = fnvAdd(h, buffer.data(), std::size_t(in.gcount()));
    if (in.bad()) throw IoError(msg(path, ": cannot read"));
    return hex16(h);
}

std::string inputsDigest(const std::vector<std::string>& paths)
{
    std::string all;
    for (const std::string& p : paths) {
        if (p.empty()) continue;
        std::error_code ec;
        const fs::file_status st = fs::status(p, ec);
        all += fs::is_regular_file(st) ? fileDigest(p) : fs::exists(st) ? "not-a-file" : "missing";
        all += "\n";
    }
    return fnv1a64(all);
}

bool isManifestLock(const std::string& fileName)
{
    return fileName.rfind(".manifest", 0) == 0 && fs::path(fileName).extension() == ".lock";
}

std::string manifestName(const Shard& shard)
{
    return shard.whole() ? "manifest.json" : msg("manifest.shard-", shard.index, ".json");
}

SequenceResult runSequence(const SequenceRun& run, const ItemRunner& runItem, const ItemSummary& summary)
{
    SequenceResult result;
    result.manifest = (fs::path(run.dir) / manifestName(run.shard)).string();
    checkOutputPath(result.manifest); // before the first item: not a symlink, a folder or a device
    const ManifestLock lock(result.manifest);
    std::vector<int> mine;
    for (int item : run.items)
        if (run.owns ? run.owns(item) : run.shard.contains(item)) mine.push_back(item);
    const std::map<int, json> finished = finishedEntries(run);
    // A run over other frames with the same settings (--frames) adds to the manifest it finds.
    std::map<int, json> entries;
    std::set<int> items(run.items.begin(), run.items.end());
    std::error_code ec;
    if (fs::exists(result.manifest, ec)) {
        try {
            const json old = readManifest(result.manifest);
            if (old.value("settingsHash", std::string()) == run.settingsHash) {
                for (const json& e : old["entries"]) { // a done entry whose files no longer verify is not carried
                    const int item = e[run.itemName].get<int>();
                    if (e["status"] != "done") entries[item] = e;
                    else if (finished.count(item)) entries[item] = finished.at(item);
                }
                for (const json& i : old["items"]) items.insert(i.get<int>());
            }
        } catch (const std::exception&) {
        }
    }
    double computedMs = 0;
    int computed = 0;
    for (std::size_t i = 0; i < mine.size(); ++i) {
        const int item = mine[i];
        const std::string where = msg(run.itemName, " ", item, " (", i + 1, "/", mine.size(), ")");
        const std::string reads = run.inputsOf ? run.inputsOf(item) : "";
        if (finished.count(item) && finished.at(item).value("inputs", std::string()) == reads) {
            entries[item] = finished.at(item);
            ++result.resumed;
            progress(msg(where, ": files match the manifest, skipped"));
            writeManifest(run, result.manifest, entries, items);
            continue;
        }
        json entry = runOne(run, item, runItem);
        if (!reads.empty()) entry["inputs"] = reads;
        computedMs += entry["ms"].get<double>();
        ++computed;
        const double eta = computedMs / computed * double(mine.size() - i - 1) / 1000.0;
        const bool ok = entry["status"] == "done";
        ok ? ++result.done : ++result.failed;
        char times[64];
        std::snprintf(times, sizeof times, "%.2f s, ETA %.0f s", entry["ms"].get<double>() / 1000.0, eta);
        progress(msg(where, ": ", ok ? summary(entry) : "FAILED: " + entry["message"].get<std::string>(), ", ", times));
        entries[item] = std::move(entry);
        writeManifest(run, result.manifest, entries, items);
    }
    if (mine.empty()) writeManifest(run, result.manifest, entries, items);
    result.entries = json::array();
    for (const auto& [item, entry] : entries) result.entries.push_back(entry);
    return result;
}

json parseManifest(const std::string& text, const std::string& path)
{
    json m;
    try {
        m = parseJson(text);
    } catch (const json::exception& e) { // parse_error, and out_of_range for numbers beyond double
        throw InputError(msg(path, ": not a manifest (invalid JSON: ", e.what(), ")"));
    }
    checkManifest(m, path);
    return m;
}

void checkManifest(const json& m, const std::string& path)
{
    auto bad = [&](const std::string& what) { throw InputError(msg(path, ": not a manifest of splatwarp: ", what)); };
    if (!m.is_object()) bad("not a JSON object");
    for (const char* key : {"settingsHash", "itemName"})
        if (!m.contains(key) || !m[key].is_string()) bad(msg("needs \"", key, "\" (a string)"));
    const std::string item = m["itemName"];
    if (item != "frame" && item != "job") bad("\"itemName\" must be \"frame\" or \"job\"");
    if (!m.contains("items") || !m["items"].is_array() || !std::all_of(m["items"].begin(), m["items"].end(), isItemNumber))
        bad("needs \"items\" (an array of whole numbers 0 .. 10^7)");
    const json& shard = m.contains("shard") ? m["shard"] : json();
    if (!shard.is_object() || !isWholeNumber(shard.value("index", json())) || !isWholeNumber(shard.value("count", json())) ||
        shard["count"].get<long long>() < 1 || shard["count"].get<long long>() > 1000000 || shard["index"].get<long long>() < 0 || shard["index"] >= shard["count"])
        bad("needs \"shard\" with whole numbers 0 <= index < count");
    if (!m.contains("entries") || !m["entries"].is_array()) bad("needs \"entries\" (an array)");
    for (const json& e : m["entries"]) {
        if (!e.is_object() || !isItemNumber(e.value(item, json())) || !e.value("status", json()).is_string())
            bad(msg("every entry needs \"", item, "\" (a whole number) and \"status\" (a string)"));
        if (e["status"] != "done") continue;
        if (!e.contains("files") || !e["files"].is_array()) bad(msg(item, " ", e[item].dump(), ": a done entry needs \"files\""));
        for (const json& f : e["files"])
            if (!f.is_object() || !f.value("path", json()).is_string() || !f.value("bytes", json()).is_number_unsigned() ||
                !f.value("fnv1a64", json()).is_string())
                bad(msg(item, " ", e[item].dump(), ": each file needs \"path\", \"bytes\" and \"fnv1a64\""));
    }
}

std::string unverifiedFiles(const std::string& dir, const json& entry, const std::string& itemName,
                            const std::function<bool(int, const std::string&)>& fileBelongs)
{
    const int item = entry[itemName].get<int>();
    if (entry["files"].empty()) return msg(itemName, " ", item, ": is done but lists no files");
    for (const json& f : entry["files"]) {
        const std::string rel = f["path"];
        std::string path;
        try {
            path = pathInside(dir, rel, rel);
        } catch (const InputError& e) {
            return e.what();
        }
        if (fileBelongs && !fileBelongs(item, rel)) return msg(rel, ": is not a file of ", itemName, " ", item);
        struct stat st {};
        if (::lstat(path.c_str(), &st) != 0) return msg(rel, ": is missing");
        if (!S_ISREG(st.st_mode)) return msg(rel, ": is not a regular file");
        if (std::uintmax_t(st.st_size) != f["bytes"].get<std::uintmax_t>())
            return msg(rel, ": has ", st.st_size, " bytes, the manifest says ", f["bytes"].get<std::uintmax_t>());
        if (fileDigest(path) != f["fnv1a64"].get<std::string>()) return msg(rel, ": its digest differs from the manifest's");
    }
    return "";
}

namespace {

/// The shard manifests of dir, checked against each other.
std::vector<json> shardManifests(const std::string& dir)
{
    std::vector<json> shards;
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(dir, ec))
        if (e.path().filename().string().rfind("manifest.shard-", 0) == 0 && e.path().extension() == ".json") {
            if (e.is_symlink(ec) || !e.is_regular_file(ec)) throw InputError(msg(e.path().string(), ": not a regular file"));
            shards.push_back(readManifest(e.path()));
            shards.back()["_path"] = e.path().string();
        }
    if (ec) throw IoError(msg(dir, ": cannot list: ", ec.message()));
    if (shards.empty()) throw InputError(msg(dir, ": no manifest.shard-*.json to merge"));
    const json& first = shards.front();
    for (const json& s : shards) {
        const std::string where = s["_path"];
        if (s["settingsHash"] != first["settingsHash"] || s["itemName"] != first["itemName"])
            throw InputError(msg(dir, ": shard manifests were written with different specs or settings (settingsHash differs: ", where, ")"));
        if (s["items"] != first["items"] || s["shard"]["count"] != first["shard"]["count"])
            throw InputError(msg(where, ": lists other items or another shard count than ", first["_path"].get<std::string>()));
    }
    return shards;
}

/// The manifest.json of dir when it was written with the shards' settings (a whole run, an earlier
/// merge): its done entries count too, so a merge never replaces it by one with fewer.
std::optional<json> earlierWhole(const fs::path& path, const json& shard)
{
    std::error_code ec;
    if (!fs::is_regular_file(fs::symlink_status(path, ec))) return std::nullopt;
    try {
        json m = readManifest(path);
        if (m["settingsHash"] == shard["settingsHash"] && m["itemName"] == shard["itemName"]) return m;
    } catch (const Error&) {
    }
    return std::nullopt;
}

} // namespace

json readShardManifest(const std::string& dir) { return shardManifests(dir).front(); }

json mergeManifests(const std::string& dir, const std::function<bool(int, const std::string&)>& fileBelongs)
{
    const fs::path wholePath = fs::path(dir) / "manifest.json";
    checkOutputPath(wholePath.string());
    const ManifestLock lock(wholePath.string());
    std::vector<json> shards = shardManifests(dir);
    json merged = shards.front();
    merged.erase("_path");
    const std::string itemName = merged["itemName"];
    std::set<int> runItems = merged["items"].get<std::set<int>>();
    std::set<int> found;
    for (const json& s : shards) found.insert(s["shard"]["index"].get<int>());
    const std::optional<json> whole = earlierWhole(wholePath, merged);
    if (whole)
        for (const json& i : (*whole)["items"]) runItems.insert(i.get<int>());
    std::map<int, json> entries;
    std::map<std::string, int> owner; // file -> the item whose verified entry lists it
    auto take = [&](json e, const std::string& from) {
        const int item = e[itemName].get<int>();
        if (!runItems.count(item)) throw InputError(msg(from, ": ", itemName, " ", item, " is not an item of the run"));
        if (e["status"] == "done") {
            std::string why = unverifiedFiles(dir, e, itemName, fileBelongs);
            for (const json& f : e["files"])
                if (why.empty() && owner.count(f["path"]) && owner[f["path"]] != item)
                    why = msg(f["path"].get<std::string>(), ": is listed by ", itemName, " ", owner[f["path"]], " too");
            if (!why.empty()) e = {{itemName, item}, {"status", "failed"}, {"message", "merge: " + why}};
            else
                for (const json& f : e["files"]) owner[f["path"]] = item;
        }
        if (!entries.count(item) || e["status"] == "done") entries[item] = e;
    };
    for (const json& s : shards)
        for (const json& e : s["entries"]) take(e, s["_path"].get<std::string>());
    if (whole) // fills the items no shard lists: a shard's entry (a forged one too) is never hidden behind it
        for (const json& e : (*whole)["entries"])
            if (!entries.count(e[itemName].get<int>())) take(e, wholePath.string());
    json missing = json::array(), failed = json::array();
    for (int i : runItems) {
        const auto it = entries.find(i);
        if (it == entries.end()) missing.push_back(i);
        else if (it->second["status"] != "done") failed.push_back(i);
    }
    const int count = merged["shard"]["count"].get<int>();
    merged["items"] = runItems;
    merged["shard"] = {{"index", 0}, {"count", 1}, {"source", "merge"}};
    merged["shards"] = {{"count", count}, {"found", found}};
    merged["entries"] = json::array();
    for (const auto& [item, entry] : entries) merged["entries"].push_back(entry);
    merged["missing"] = missing;
    merged["failed"] = failed;
    writeFileAtomic(wholePath.string(), merged.dump(2) + "\n");
    return merged;
}

std::string mergeFailures(const json& merged)
{
    std::string out;
    int shown = 0;
    for (const json& e : merged["entries"])
        if (e["status"] != "done" && shown++ < 5)
            out += msg("\n  ", merged["itemName"].get<std::string>(), " ", e[merged["itemName"].get<std::string>()].get<int>(), ": ",
                       e.value("message", std::string("failed")));
    return out;
}

} // namespace splatwarp
