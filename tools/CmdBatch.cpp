/// `splatwarp batch JOBS.json -o DIR`: a list of deform/animate/to-vdb/from-vdb jobs run in this process,
/// with the shards, resume and manifest rules of `animate` (job/Sequence.h).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>

#include "Command.h"
#include "job/JobList.h"
#include "job/Sequence.h"
#include "job/Shard.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "splatwarp/Version.h"

namespace splatwarp::cli {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

struct BatchArgs {
    std::string jobsPath, outDir, shard, merge;
    int shardCount = 0;
};

/// A temporary of core/AtomicFile (".sw<pid>-<n>.tmp") that a killed run left behind: not an output.
bool isStaleTemporary(const fs::path& p)
{
    const std::string name = p.filename().string();
    return name.rfind(".sw", 0) == 0 && p.extension() == ".tmp";
}

/// Files under a job's output (a folder or one file), relative to DIR, sorted; symlinks are not
/// followed (a job writes none) and not listed.
json outputFiles(const fs::path& dir, const std::string& output)
{
    std::vector<std::string> files;
    const fs::path out = dir / output;
    std::error_code ec;
    if (fs::is_regular_file(fs::symlink_status(out, ec))) files.push_back(output);
    else if (fs::is_directory(fs::symlink_status(out, ec)))
        for (const fs::directory_entry& e : fs::recursive_directory_iterator(out, ec))
            if (e.is_regular_file(ec) && !e.is_symlink(ec) && !isStaleTemporary(e.path()) && !isManifestLock(e.path().filename().string()))
                files.push_back(fs::relative(e.path(), dir).string());
    std::sort(files.begin(), files.end());
    return files;
}

/// Run one job's command in this process, as `splatwarp KIND INPUT ARGS... -o DIR/OUTPUT`.
json runJob(const BatchJob& job, const std::string& outputPath, const fs::path& dir)
{
    std::vector<std::string> words = {"splatwarp", job.kind->name, job.input};
    words.insert(words.end(), job.args.begin(), job.args.end());
    words.push_back("-o");
    words.push_back(outputPath);
    std::vector<char*> argv;
    for (std::string& w : words) argv.push_back(w.data());
    const SchedulerEnvironmentIgnored whole; // batch shards the job list: each job runs all of its frames
    CLI::App app;
    app.require_subcommand(1);
    addCommands(app);
    app.parse(int(argv.size()), argv.data()); // the subcommand's callback runs the job
    return {{"kind", job.kind->name}, {"files", outputFiles(dir, job.output)}};
}

/// Whether a file (relative to DIR) lies under a job's output.
bool underOutput(const std::string& output, const std::string& rel)
{
    const std::string out = fs::path(output).lexically_normal().string();
    const std::string file = fs::path(rel).lexically_normal().string();
    return file == out || file.rfind(out + "/", 0) == 0;
}

/// Which files (relative to DIR) may be each job's: those under its output.
std::function<bool(int, const std::string&)> jobFiles(const std::vector<BatchJob>& jobs)
{
    return [jobs](int j, const std::string& rel) { return j >= 0 && j < int(jobs.size()) && underOutput(jobs[std::size_t(j)].output, rel); };
}

/// The job list the shards of dir ran (`jobsPath`, else the one their manifests name), for merge
/// to check each job's files as resume does. @throws InputError when it is not the one they ran.
std::vector<BatchJob> mergedJobs(const std::string& dir, const std::string& jobsPath)
{
    const json shard = readShardManifest(dir);
    const std::string path = !jobsPath.empty() ? jobsPath : shard.value("jobs", std::string());
    std::error_code ec;
    if (path.empty() || !fs::is_regular_file(path, ec))
        throw InputError(msg(dir, ": cannot find the job list its shards ran (", path.empty() ? "unnamed" : path,
                             "), needed to check whose files each job lists: give it, batch JOBS.json --merge ", dir));
    const std::string text = readWholeFile(path, "job list");
    if (fnv1a64(text) != shard["settingsHash"])
        throw InputError(msg(path, ": is not the job list the shards of ", dir, " ran (its hash differs from their settingsHash)"));
    return parseJobList(text, path);
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
            const json merged = mergeManifests(args->merge, jobFiles(mergedJobs(args->merge, args->jobsPath)));
            std::printf("merged: %zu jobs, missing %s, failed %s\n", merged["entries"].size(), merged["missing"].dump().c_str(),
                        merged["failed"].dump().c_str());
            if (!merged["missing"].empty() || !merged["failed"].empty())
                throw InputError(msg(args->merge, ": jobs missing ", merged["missing"].dump(), ", failed ", merged["failed"].dump(),
                                     mergeFailures(merged)));
            return;
        }
        if (args->jobsPath.empty() || args->outDir.empty()) throw UsageError("batch needs JOBS.json and -o DIR (or --merge DIR)");
        const std::string text = readWholeFile(args->jobsPath, "job list");
        const std::vector<BatchJob> jobs = parseJobList(text, args->jobsPath);
        const Shard shard = resolveShard(args->shard, args->shardCount);
        const std::vector<std::string> outputs = checkJobPaths(jobs, args->outDir, args->jobsPath); // before any job runs
        DirectoryGuard dirs;
        dirs.create(args->outDir);
        SequenceRun run;
        run.dir = args->outDir;
        run.itemName = "job";
        run.shard = shard;
        run.fileBelongs = jobFiles(jobs);
        run.inputsOf = [&](int j) { return inputsDigest(jobs[std::size_t(j)].reads); }; // an edited model or spec reruns its job
        for (int j = 0; j < int(jobs.size()); ++j) run.items.push_back(j);
        run.settingsHash = fnv1a64(text);
        run.header = {{"tool", "splatwarp"}, {"version", SPLATWARP_VERSION_STRING}, {"command", "batch"},
                      {"jobs", args->jobsPath}, {"specHash", fnv1a64(text)}};
        const SequenceResult r = runSequence(
            run, [&](int j) { return runJob(jobs[std::size_t(j)], outputs[std::size_t(j)], args->outDir); },
            [&](const json& e) { return msg(e["kind"].get<std::string>(), ", ", e["files"].size(), " files"); });
        dirs.keep();
        std::printf("jobs: %d done, %d resumed, %d failed (shard %d/%d from %s); manifest %s\n", r.done, r.resumed, r.failed,
                    run.shard.index, run.shard.count, run.shard.source.c_str(), r.manifest.c_str());
        if (r.failed > 0) throw InputError(msg(r.failed, " job(s) failed; their messages are in ", r.manifest));
    });
});

} // namespace
} // namespace splatwarp::cli
