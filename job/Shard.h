#pragma once
/// @file Shard.h
/// @brief Which frames (or jobs) one process of a sharded run takes: item f belongs to shard I of N
///        when f mod N = I (`animate --warm-start`: contiguous ranges instead, job/WarmStart.h).
///        From --shard I/N or the scheduler's environment (Slurm job arrays, Kubernetes Indexed
///        Jobs); the result says which.
#include <functional>
#include <string>

namespace splatwarp {

struct Shard {
    int index = 0, count = 1;
    std::string source = "none"; ///< "--shard", "SLURM_ARRAY_TASK_ID" or "JOB_COMPLETION_INDEX"
    bool contains(int item) const { return item % count == index; }
    bool whole() const { return count == 1; }
};

/// @brief Environment lookup (getenv, or a map in tests); returns null when unset.
using EnvLookup = std::function<const char*(const char*)>;

/// @brief The shard of this process. `flag` is --shard "I/N" (empty: not given), `shardCount`
///        is --shard-count (0: not given). Without the flag: (SLURM_ARRAY_TASK_ID minus
///        SLURM_ARRAY_TASK_MIN) / SLURM_ARRAY_TASK_STEP of SLURM_ARRAY_TASK_COUNT tasks, else
///        JOB_COMPLETION_INDEX of --shard-count, else the whole run.
/// @throws UsageError for a malformed I/N, I >= N, N < 1, --shard with --shard-count, a task ID
///         off its array's step, or JOB_COMPLETION_INDEX without --shard-count.
Shard resolveShard(const std::string& flag, int shardCount, const EnvLookup& env);

/// @brief While one lives, resolveShard(flag, shardCount) on this thread reads no scheduler
///        variable: `batch` runs each job whole (it shards the job list, not a job's frames).
class SchedulerEnvironmentIgnored {
public:
    SchedulerEnvironmentIgnored();
    ~SchedulerEnvironmentIgnored();
    SchedulerEnvironmentIgnored(const SchedulerEnvironmentIgnored&) = delete;
    SchedulerEnvironmentIgnored& operator=(const SchedulerEnvironmentIgnored&) = delete;

private:
    bool mWas;
};

/// @brief resolveShard() with the process environment (none inside SchedulerEnvironmentIgnored).
Shard resolveShard(const std::string& flag, int shardCount);

} // namespace splatwarp
