/// `splatwarp batch JOBS.json -o DIR`: a list of deform/animate/to-vdb/from-vdb jobs run in this process,
/// with the shards, resume and manifest rules of `animate` (job/Sequence.h).
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "Command.h"
#include "Sequence.h"
#include "Shard.h"
#include "core/Error.h"
#include "splatwarp/Version.h"

namespace splatwarp::cli {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

/// The commands a batch can run and the flag that names their output (folder or file) under DIR.
/// A new job kind is one more line.
struct JobKind {
    const char* name;
    const char* outputFlag;
};
const JobKind kJobKinds[] = {{"deform", "-o"}, {"animate", "-o"}, {"to-vdb", "-o"}, {"from-vdb", "-o"}};

struct BatchArgs {
    std::string jobsPath, outDir, shard, merge;
    int shardCount = 0;
};

const JobKind& jobKind(const json& job, const std::string& where)
{
    const std::string kind = job.value("kind", std::string());
    for (const JobKind& k : kJobKinds)
        if (kind == k.name) return k;
    std::string list;
    for (const JobKind& k : kJobKinds) list += std::string(list.empty() ? "" : ", ") + k.name;
    throw InputError(msg(where, "\"kind\" must be one of ", list, " (got \"", kind, "\")"));
}

/// Parse and check JOBS.json: {"jobs": [{"kind", "input", "output", "args": [...]}, ...]}.
json loadJobs(const std::string& path, std::string& text)
{
    text = readTextFile(path, "job list");
    json root;
    try {
        root = json::parse(text);
    } catch (const json::exception& e) {
        throw InputError(msg(path, ": invalid JSON: ", e.what()));
    }
    if (!root.is_object() || !root.contains("jobs") || !root["jobs"].is_array() || root["jobs"].empty())
        throw InputError(msg(path, ": needs \"jobs\": a non-empty array"));
    for (std::size_t i = 0; i < root["jobs"].size(); ++i) {
        const json& job = root["jobs"][i];
        const std::string where = msg(path, ": job ", i, ": ");
        if (!job.is_object()) throw InputError(where + "must be a JSON object");
        jobKind(job, where);
        for (const char* key : {"input", "output"})
            if (!job.contains(key) || !job[key].is_string() || job[key].get<std::string>().empty())
                throw InputError(msg(where, "needs \"", key, "\" (a path)"));
        if (job.contains("args") && (!job["args"].is_array() ||
                                     !std::all_of(job["args"].begin(), job["args"].end(), [](const json& a) { return a.is_string(); })))
            throw InputError(where + "\"args\" must be an array of strings (the command's flags)");
    }
    return root["jobs"];
}

/// A temporary of core/AtomicFile (".sw<pid>-<n>.tmp") that a killed run left behind: not an output.
bool isStaleTemporary(const fs::path& p)
{
    const std::string name = p.filename().string();
    return name.rfind(".sw", 0) == 0 && p.extension() == ".tmp";
}

/// Files under a job's output (a folder or one file), relative to DIR, sorted.
json outputFiles(const fs::path& dir, const std::string& output)
{
    std::vector<std::string> files;
    const fs::path out = dir / output;
    if (fs::is_regular_file(out)) files.push_back(output);
    else if (fs::is_directory(out))
        for (const fs::directory_entry& e : fs::recursive_directory_iterator(out))
            if (e.is_regular_file() && !isStaleTemporary(e.path())) files.push_back(fs::relative(e.path(), dir).string());
    std::sort(files.begin(), files.end());
    return files;
}

/// Run one job's command in this process, as `splatwarp KIND INPUT ARGS... -o DIR/OUTPUT`.
json runJob(const json& job, const fs::path& dir)
{
    const JobKind& kind = jobKind(job, "");
    std::vector<std::string> words = {"splatwarp", kind.name, job["input"].get<std::string>()};
    for (const json& a : job.value("args", json::array())) words.push_back(a.get<std::string>());
    words.push_back(kind.outputFlag);
    words.push_back((dir / job["output"].get<std::string>()).string());
    std::vector<char*> argv;
    for (std::string& w : words) argv.push_back(w.data());
    CLI::App app;
    app.require_subcommand(1);
    addCommands(app);
    app.parse(int(argv.size()), argv.data()); // the subcommand's callback runs the job
    return {{"kind", kind.name}, {"files", outputFiles(dir, job["output"].get<std::string>())}};
}

const CommandRegistrar reg(37, [](CLI::App& app) {
    auto args = std::make_shared<BatchArgs>();
    CLI::App* sub = app.add_subcommand(
        "batch", "Run a list of jobs (deform, animate, to-vdb, from-vdb) with shards, resume and a manifest: "
                 "JOBS.json = {\"jobs\": [{\"kind\", \"input\", \"output\" (under -o DIR), \"args\": [flags]}]}");
    sub->add_option("jobs", args->jobsPath, "Job list JSON");
    sub->add_option("-o,--output", args->outDir, "Output directory: each job writes DIR/<output>; DIR/manifest.json");
    sub->add_option("--shard", args->shard, "Take jobs j with j mod N = I (I/N); default from SLURM_ARRAY_TASK_ID/COUNT or JOB_COMPLETION_INDEX");
    sub->add_option("--shard-count", args->shardCount, "Shard count N with JOB_COMPLETION_INDEX")->check(positive());
    sub->add_option("--merge", args->merge, "Join DIR/manifest.shard-*.json into DIR/manifest.json and list missing or failed jobs");
    sub->callback([args] {
        if (!args->merge.empty()) {
            const json merged = mergeManifests(args->merge);
            std::printf("merged: %zu jobs, missing %s, failed %s\n", merged["entries"].size(), merged["missing"].dump().c_str(),
                        merged["failed"].dump().c_str());
            if (!merged["missing"].empty() || !merged["failed"].empty())
                throw InputError(msg(args->merge, ": jobs missing ", merged["missing"].dump(), ", failed ", merged["failed"].dump()));
            return;
        }
        if (args->jobsPath.empty() || args->outDir.empty()) throw UsageError("batch needs JOBS.json and -o DIR (or --merge DIR)");
        std::string text;
        const json jobs = loadJobs(args->jobsPath, text);
        std::error_code ec;
        fs::create_directories(args->outDir, ec);
        if (ec) throw IoError(msg(args->outDir, ": cannot create output directory: ", ec.message()));
        SequenceRun run;
        run.dir = args->outDir;
        run.itemName = "job";
        run.shard = resolveShard(args->shard, args->shardCount);
        for (int j = 0; j < int(jobs.size()); ++j) run.items.push_back(j);
        run.settingsHash = fnv1a64(text);
        run.header = {{"tool", "splatwarp"}, {"version", SPLATWARP_VERSION_STRING}, {"command", "batch"},
                      {"jobs", args->jobsPath}, {"specHash", fnv1a64(text)}};
        const SequenceResult r = runSequence(
            run, [&](int j) { return runJob(jobs[std::size_t(j)], args->outDir); },
            [&](const json& e) { return msg(e["kind"].get<std::string>(), ", ", e["files"].size(), " files"); });
        std::printf("jobs: %d done, %d resumed, %d failed (shard %d/%d from %s); manifest %s\n", r.done, r.resumed, r.failed,
                    run.shard.index, run.shard.count, run.shard.source.c_str(), r.manifest.c_str());
        if (r.failed > 0) throw InputError(msg(r.failed, " job(s) failed; their messages are in ", r.manifest));
    });
});

} // namespace
} // namespace splatwarp::cli
