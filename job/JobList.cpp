#include "job/JobList.h"

#include <algorithm>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "core/Error.h"
#include "core/SafePath.h"
#include "job/Recipe.h"
#include "io/JsonText.h"

namespace splatwarp {

namespace fs = std::filesystem;
using json = nlohmann::json;

const std::vector<JobKind>& jobKinds()
{
    static const std::vector<JobKind> kinds = {
        {"deform", {"-o", "--output"}, {"--spec", "--recipe"}},
        {"animate", {"-o", "--output", "--merge"}, {"--spec", "--recipe"}},
        {"to-vdb", {"-o", "--output"}, {"--spec"}},
        {"from-vdb", {"-o", "--output", "--report"}, {}},
    };
    return kinds;
}

namespace {

const JobKind& kindOf(const json& job, const std::string& where)
{
    const json kind = job.contains("kind") ? job["kind"] : json();
    for (const JobKind& k : jobKinds())
        if (kind.is_string() && kind.get<std::string>() == k.name) return k;
    std::string list;
    for (const JobKind& k : jobKinds()) list += std::string(list.empty() ? "" : ", ") + k.name;
    throw InputError(msg(where, "\"kind\" must be one of ", list, " (got ", kind.is_null() ? "nothing" : kind.dump(), ")"));
}

std::string pathField(const json& job, const char* key, const std::string& where)
{
    if (!job.contains(key) || !job[key].is_string() || job[key].get<std::string>().empty())
        throw InputError(msg(where, "needs \"", key, "\" (a path)"));
    return job[key].get<std::string>();
}

/// The flag a word of "args" names ("--report=x" -> "--report", "-ox" -> "-o"), or "" for a value.
std::string flagOf(const std::string& word)
{
    if (word.rfind("--", 0) == 0) return word.substr(0, word.find('='));
    if (word.size() >= 2 && word[0] == '-' && std::isalpha(static_cast<unsigned char>(word[1]))) return word.substr(0, 2);
    return "";
}

/// Why a flag has no place in a job's "args" whatever its kind, or "" when it may be there.
std::string refusedFlag(const std::string& flag)
{
    if (flag.rfind("--help", 0) == 0 || flag == "-h") return "help prints and stops; a job must run (see `splatwarp KIND --help`)";
    if (flag == "--shard" || flag == "--shard-count")
        return "batch runs each job whole and shards the job list (give --shard to batch itself)";
    return "";
}

/// The args checked against the kind's path flags; the read flags' values are added to reads.
void checkArgs(const JobKind& kind, const std::vector<std::string>& args, const std::string& where, std::vector<std::string>& reads)
{
    for (std::size_t i = 0; i < args.size(); ++i) {
        const std::string flag = flagOf(args[i]);
        if (flag.empty()) continue;
        if (const std::string why = refusedFlag(flag); !why.empty())
            throw InputError(msg(where, "\"args\" may not hold ", args[i], ": ", why));
        auto has = [&](const std::vector<std::string>& list) { return std::find(list.begin(), list.end(), flag) != list.end(); };
        if (has(kind.writeFlags))
            throw InputError(msg(where, "\"args\" may not name an output (", args[i],
                                 "): a job writes only its \"output\", inside the batch's folder"));
        if (!has(kind.readFlags)) continue;
        const std::size_t eq = args[i].find('=');
        std::string value;
        if (eq != std::string::npos) value = args[i].substr(eq + 1);
        else if (flag.size() == 2 && args[i].size() > 2) value = args[i].substr(2);
        else if (i + 1 < args.size()) value = args[++i];
        if (value.empty() || (flag == "--recipe" && !isRecipeFile(value))) continue; // a built-in recipe is no file
        reads.push_back(value);
    }
}

BatchJob parseJob(const json& job, const std::string& where)
{
    if (!job.is_object()) throw InputError(where + "must be a JSON object");
    for (auto it = job.begin(); it != job.end(); ++it)
        if (it.key() != "kind" && it.key() != "input" && it.key() != "output" && it.key() != "args")
            throw InputError(msg(where, "unknown key \"", it.key(), "\" (a job has \"kind\", \"input\", \"output\" and \"args\")"));
    BatchJob out;
    out.kind = &kindOf(job, where);
    out.input = pathField(job, "input", where);
    out.output = pathField(job, "output", where);
    if (job.contains("args")) {
        const json& a = job["args"];
        if (!a.is_array() || !std::all_of(a.begin(), a.end(), [](const json& w) { return w.is_string(); }))
            throw InputError(where + "\"args\" must be an array of strings (the command's flags)");
        for (const json& w : a) out.args.push_back(w.get<std::string>());
    }
    out.reads = {out.input};
    checkArgs(*out.kind, out.args, where, out.reads);
    return out;
}

bool isManifestName(const std::string& first)
{
    return first.rfind("manifest", 0) == 0 && fs::path(first).extension() == ".json";
}

} // namespace

std::vector<BatchJob> parseJobList(const std::string& text, const std::string& path)
{
    json root;
    try {
        root = parseJson(text);
    } catch (const json::exception& e) {
        throw InputError(msg(path, ": invalid JSON: ", e.what()));
    }
    if (!root.is_object() || !root.contains("jobs") || !root["jobs"].is_array() || root["jobs"].empty())
        throw InputError(msg(path, ": needs \"jobs\": a non-empty array"));
    std::vector<BatchJob> jobs;
    for (std::size_t i = 0; i < root["jobs"].size(); ++i) jobs.push_back(parseJob(root["jobs"][i], msg(path, ": job ", i, ": ")));
    return jobs;
}

std::vector<std::string> checkJobPaths(const std::vector<BatchJob>& jobs, const std::string& dir, const std::string& jobsPath)
{
    // Each path resolved once (a file-system walk each); the pairs below compare strings only.
    std::vector<std::string> outputs, placed;
    const std::string list = resolvedPath(jobsPath);
    for (std::size_t i = 0; i < jobs.size(); ++i) {
        const std::string where = msg(jobsPath, ": job ", i, ": \"output\" ", jobs[i].output);
        outputs.push_back(pathInside(dir, jobs[i].output, where));
        placed.push_back(resolvedPath(outputs[i]));
        const std::string first = fs::path(jobs[i].output).lexically_normal().begin()->string();
        if (isManifestName(first)) throw InputError(msg(where, ": is the name of a batch manifest"));
        if (isWithinResolved(placed[i], list)) throw InputError(msg(where, ": would overwrite the job list"));
        for (std::size_t j = 0; j < i; ++j)
            if (isWithinResolved(placed[j], placed[i]) || isWithinResolved(placed[i], placed[j]))
                throw InputError(msg(where, ": is also the output of job ", j, " (", jobs[j].output, ") or lies inside it or around it"));
    }
    std::vector<std::vector<std::string>> reads;
    for (const BatchJob& job : jobs) {
        reads.emplace_back();
        for (const std::string& in : job.reads) reads.back().push_back(resolvedPath(in));
    }
    for (std::size_t i = 0; i < jobs.size(); ++i)
        for (std::size_t j = 0; j <= i; ++j) // job i's output against the inputs of job i and of every job before it
            for (std::size_t k = 0; k < reads[j].size(); ++k)
                if (isWithinResolved(placed[i], reads[j][k]))
                    throw InputError(msg(jobsPath, ": job ", i, ": \"output\" ", jobs[i].output, " would overwrite ",
                                         j == i ? "its own input " : msg("the input of job ", j, " "), jobs[j].reads[k]));
    return outputs;
}

} // namespace splatwarp
