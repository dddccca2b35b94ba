#include "job/Shard.h"

#include <cstdlib>

#include "core/Error.h"

namespace splatwarp {

namespace {

int nonNegative(const std::string& text, const std::string& what)
{
    std::size_t used = 0;
    long v = -1;
    try {
        v = std::stol(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used == 0 || used != text.size() || v < 0 || v > 1000000)
        throw UsageError(msg(what, " must be a whole number 0..1000000 (got \"", text, "\")"));
    return int(v);
}

Shard checked(Shard s)
{
    if (s.count < 1) throw UsageError(msg("shard count must be >= 1 (got ", s.count, ", from ", s.source, ")"));
    if (s.index < 0) // SLURM_ARRAY_TASK_MIN above SLURM_ARRAY_TASK_ID
        throw UsageError(msg("shard index ", s.index, " is negative (from ", s.source, ": SLURM_ARRAY_TASK_MIN above SLURM_ARRAY_TASK_ID?)"));
    if (s.index >= s.count)
        throw UsageError(msg("shard index ", s.index, " must be below the shard count ", s.count, " (from ", s.source, ")"));
    return s;
}

/// The task's place in its array: (ID - MIN) / STEP (--array=0-6:2 has tasks 0, 2, 4, 6: shards 0..3).
int slurmTask(const char* id, const char* lo, const char* step)
{
    const int offset = nonNegative(id, "SLURM_ARRAY_TASK_ID") - (lo ? nonNegative(lo, "SLURM_ARRAY_TASK_MIN") : 0);
    const int by = step ? nonNegative(step, "SLURM_ARRAY_TASK_STEP") : 1;
    if (by < 1) throw UsageError("SLURM_ARRAY_TASK_STEP must be >= 1 (got 0)");
    if (offset % by != 0)
        throw UsageError(msg("SLURM_ARRAY_TASK_ID ", id, " is not SLURM_ARRAY_TASK_MIN plus a multiple of SLURM_ARRAY_TASK_STEP ", by));
    return offset / by; // negative (MIN above ID) is refused by checked()
}

thread_local bool tSchedulerIgnored = false;

} // namespace

SchedulerEnvironmentIgnored::SchedulerEnvironmentIgnored() : mWas(tSchedulerIgnored) { tSchedulerIgnored = true; }
SchedulerEnvironmentIgnored::~SchedulerEnvironmentIgnored() { tSchedulerIgnored = mWas; }

Shard resolveShard(const std::string& flag, int shardCount, const EnvLookup& env)
{
    Shard s;
    if (!flag.empty()) {
        if (shardCount > 0) throw UsageError("give --shard I/N or --shard-count N, not both (--shard's N is the count)");
        const std::size_t slash = flag.find('/');
        if (slash == std::string::npos) throw UsageError(msg("--shard must be I/N, e.g. 0/4 (got \"", flag, "\")"));
        s.source = "--shard";
        s.index = nonNegative(flag.substr(0, slash), "--shard I");
        s.count = nonNegative(flag.substr(slash + 1), "--shard N");
        return checked(s);
    }
    if (const char* id = env("SLURM_ARRAY_TASK_ID")) {
        s.source = "SLURM_ARRAY_TASK_ID";
        const char* count = env("SLURM_ARRAY_TASK_COUNT");
        s.index = slurmTask(id, env("SLURM_ARRAY_TASK_MIN"), env("SLURM_ARRAY_TASK_STEP"));
        if (shardCount > 0) s.count = shardCount;
        else if (count) s.count = nonNegative(count, "SLURM_ARRAY_TASK_COUNT");
        else throw UsageError("SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not: give --shard-count N");
        return checked(s);
    }
    if (const char* index = env("JOB_COMPLETION_INDEX")) {
        s.source = "JOB_COMPLETION_INDEX";
        if (shardCount <= 0)
            throw UsageError("JOB_COMPLETION_INDEX is set: give --shard-count N (the Job's completions)");
        s.index = nonNegative(index, "JOB_COMPLETION_INDEX");
        s.count = shardCount;
        return checked(s);
    }
    if (shardCount > 1) throw UsageError("--shard-count needs --shard, SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX");
    return s;
}

Shard resolveShard(const std::string& flag, int shardCount)
{
    return resolveShard(flag, shardCount,
                        [](const char* name) { return tSchedulerIgnored ? nullptr : static_cast<const char*>(std::getenv(name)); });
}

} // namespace splatwarp
