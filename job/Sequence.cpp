#include "Sequence.h"

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"

namespace splatwarp {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

json readManifest(const fs::path& path)
{
    try {
        return json::parse(readTextFile(path.string(), "manifest"));
    } catch (const json::exception& e) {
        throw InputError(msg(path.string(), ": not a manifest (invalid JSON: ", e.what(), ")"));
    }
}

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

bool filesMatch(const std::string& dir, const json& entry)
{
    if (!entry.contains("files")) return false;
    for (const json& f : entry["files"]) {
        const fs::path path = fs::path(dir) / f.value("path", std::string());
        std::error_code ec;
        if (!fs::is_regular_file(path, ec) || fs::file_size(path, ec) != f.value("bytes", std::uintmax_t(0)) ||
            fileDigest(path.string()) != f.value("fnv1a64", std::string()))
            return false;
    }
    return true;
}

/// Finished entries of earlier runs with the same settings, by item (any manifest in dir).
std::map<int, json> finishedEntries(const SequenceRun& run)
{
    std::map<int, json> out;
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(run.dir, ec)) {
        const std::string name = e.path().filename().string();
        if (name.rfind("manifest", 0) != 0 || e.path().extension() != ".json") continue;
        json m;
        try {
            m = readManifest(e.path());
        } catch (const Error&) {
            continue; // an unreadable manifest only costs redoing its items
        }
        if (m.value("settingsHash", std::string()) != run.settingsHash || !m.contains("entries")) continue;
        for (const json& entry : m["entries"])
            if (entry.value("status", std::string()) == "done" && filesMatch(run.dir, entry))
                out[entry.value(run.itemName, -1)] = entry;
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

std::string fnv1a64(const std::string& bytes)
{
    std::uint64_t h = 1469598103934665603ull;
    for (unsigned char c : bytes) h = (h ^ c) * 1099511628211ull;
    char out[17];
    std::snprintf(out, sizeof out, "%016llx", static_cast<unsigned long long>(h));
    return out;
}

std::string readTextFile(const std::string& path, const std::string& what)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(msg(path, ": cannot open ", what));
    std::ostringstream s;
    s << in.rdbuf();
    if (in.bad()) throw IoError(msg(path, ": cannot read ", what));
    return s.str();
}

std::string fileDigest(const std::string& path) { return fnv1a64(readTextFile(path, "output file")); }

std::string manifestName(const Shard& shard)
{
    return shard.whole() ? "manifest.json" : msg("manifest.shard-", shard.index, ".json");
}

SequenceResult runSequence(const SequenceRun& run, const ItemRunner& runItem, const ItemSummary& summary)
{
    SequenceResult result;
    result.manifest = (fs::path(run.dir) / manifestName(run.shard)).string();
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
                for (const json& e : old["entries"]) entries[e[run.itemName].get<int>()] = e;
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
        if (finished.count(item)) {
            entries[item] = finished.at(item);
            ++result.resumed;
            progress(msg(where, ": files match the manifest, skipped"));
            writeManifest(run, result.manifest, entries, items);
            continue;
        }
        json entry = runOne(run, item, runItem);
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
    return result;
}

json mergeManifests(const std::string& dir)
{
    std::vector<json> shards;
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(dir, ec))
        if (e.path().filename().string().rfind("manifest.shard-", 0) == 0 && e.path().extension() == ".json")
            shards.push_back(readManifest(e.path()));
    if (ec) throw IoError(msg(dir, ": cannot list: ", ec.message()));
    if (shards.empty()) throw InputError(msg(dir, ": no manifest.shard-*.json to merge"));
    json merged = shards.front();
    const std::string itemName = merged.value("itemName", std::string("frame"));
    std::map<int, json> entries;
    std::set<int> found;
    for (const json& s : shards) {
        if (s.value("settingsHash", std::string()) != merged.value("settingsHash", std::string()))
            throw InputError(msg(dir, ": shard manifests were written with different specs or settings (settingsHash differs)"));
        found.insert(s["shard"]["index"].get<int>());
        for (const json& e : s["entries"]) {
            const int item = e[itemName].get<int>();
            if (!entries.count(item) || e["status"] == "done") entries[item] = e;
        }
    }
    json missing = json::array(), failed = json::array();
    for (const json& i : merged["items"]) {
        const auto it = entries.find(i.get<int>());
        if (it == entries.end()) missing.push_back(i);
        else if (it->second["status"] != "done") failed.push_back(i);
    }
    const int count = merged["shard"]["count"].get<int>();
    merged["shard"] = {{"index", 0}, {"count", 1}, {"source", "merge"}};
    merged["shards"] = {{"count", count}, {"found", found}};
    merged["entries"] = json::array();
    for (const auto& [item, entry] : entries) merged["entries"].push_back(entry);
    merged["missing"] = missing;
    merged["failed"] = failed;
    writeFileAtomic((fs::path(dir) / "manifest.json").string(), merged.dump(2) + "\n");
    return merged;
}

} // namespace splatwarp
