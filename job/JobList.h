#pragma once
/// @file JobList.h
/// @brief `batch`'s job list, read as data someone else may have written (a farm, a shared
///        folder): every job's kind, input, output and flags are checked, and every path a job
///        writes must stay inside the batch's output folder, before any job runs.
#include <string>
#include <vector>

namespace splatwarp {

/// @brief A command a batch can run: its name, and its flags that name files. A new kind, or a
///        new path flag of a kind, is one more entry here.
struct JobKind {
    const char* name;
    std::vector<std::string> writeFlags; ///< flags naming a file or folder the command writes: refused in "args"
    std::vector<std::string> readFlags;  ///< flags naming a file the command reads (its inputs beside INPUT)
};

/// @brief deform, animate, to-vdb, from-vdb.
const std::vector<JobKind>& jobKinds();

/// @brief One job: `splatwarp KIND INPUT ARGS... -o DIR/OUTPUT`.
struct BatchJob {
    const JobKind* kind = nullptr;
    std::string input, output;       ///< input as given; output relative to DIR
    std::vector<std::string> args;
    std::vector<std::string> reads;  ///< INPUT and the values of the kind's read flags
};

/// @brief Parse JOBS.json = {"jobs": [{"kind", "input", "output", "args": [...]}, ...]}: JSON,
///        kinds, types, and no write flag in "args" (`-o`, `--report`, `--merge`: a job's only
///        output is its "output"). Pure: touches no file. @throws InputError naming `path` and the job.
std::vector<BatchJob> parseJobList(const std::string& text, const std::string& path);

/// @brief The paths' rules against the file system, for all jobs before any runs; returns each
///        job's DIR/OUTPUT. Every output resolves inside `dir` (relative, no "..", no symlink
///        below dir); no two outputs are one or nest; no output is or holds the job list, a
///        manifest of DIR (manifest*.json), or an input of its job or of an earlier job (one that
///        read it before); an input in an earlier job's output is that job's product (a chain). @throws InputError naming the job.
std::vector<std::string> checkJobPaths(const std::vector<BatchJob>& jobs, const std::string& dir, const std::string& jobsPath);

} // namespace splatwarp
