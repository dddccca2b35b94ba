#include <gtest/gtest.h>

#include <cstdlib>
#include <map>

#include "job/Shard.h"
#include "core/Error.h"

using namespace splatwarp;

namespace {

EnvLookup envOf(std::map<std::string, std::string> vars)
{
    return [vars](const char* name) -> const char* {
        const auto it = vars.find(name);
        return it == vars.end() ? nullptr : it->second.c_str();
    };
}

std::string usageError(const std::string& flag, int count, const std::map<std::string, std::string>& vars)
{
    try {
        resolveShard(flag, count, envOf(vars));
    } catch (const UsageError& e) {
        return e.what();
    }
    return "";
}

} // namespace

TEST(Shard, FlagThenSlurmThenKubernetesThenWhole)
{
    const Shard flag = resolveShard("1/3", 0, envOf({{"SLURM_ARRAY_TASK_ID", "0"}, {"SLURM_ARRAY_TASK_COUNT", "2"}}));
    EXPECT_EQ(flag.index, 1);
    EXPECT_EQ(flag.count, 3);
    EXPECT_EQ(flag.source, "--shard");
    const Shard slurm = resolveShard("", 0, envOf({{"SLURM_ARRAY_TASK_ID", "5"}, {"SLURM_ARRAY_TASK_MIN", "4"},
                                                   {"SLURM_ARRAY_TASK_COUNT", "2"}, {"JOB_COMPLETION_INDEX", "0"}}));
    EXPECT_EQ(slurm.index, 1);
    EXPECT_EQ(slurm.count, 2);
    EXPECT_EQ(slurm.source, "SLURM_ARRAY_TASK_ID");
    const Shard k8s = resolveShard("", 4, envOf({{"JOB_COMPLETION_INDEX", "3"}}));
    EXPECT_EQ(k8s.index, 3);
    EXPECT_EQ(k8s.count, 4);
    EXPECT_EQ(k8s.source, "JOB_COMPLETION_INDEX");
    const Shard whole = resolveShard("", 0, envOf({}));
    EXPECT_TRUE(whole.whole());
    EXPECT_EQ(whole.source, "none");
    // f mod N = I: the shards partition the frames.
    for (int f = 0; f < 10; ++f) EXPECT_EQ(int(Shard{0, 3}.contains(f)) + int(Shard{1, 3}.contains(f)) + int(Shard{2, 3}.contains(f)), 1);
}

TEST(Shard, RefusesBadShards)
{
    EXPECT_NE(usageError("2/2", 0, {}).find("shard index 2 must be below the shard count 2"), std::string::npos);
    EXPECT_NE(usageError("1/0", 0, {}).find("shard count must be >= 1"), std::string::npos);
    EXPECT_NE(usageError("1", 0, {}).find("--shard must be I/N"), std::string::npos);
    EXPECT_NE(usageError("a/2", 0, {}).find("--shard I must be a whole number"), std::string::npos);
    EXPECT_NE(usageError("", 0, {{"JOB_COMPLETION_INDEX", "1"}}).find("give --shard-count"), std::string::npos);
    EXPECT_NE(usageError("", 2, {{"JOB_COMPLETION_INDEX", "2"}}).find("from JOB_COMPLETION_INDEX"), std::string::npos);
    EXPECT_NE(usageError("", 0, {{"SLURM_ARRAY_TASK_ID", "1"}}).find("SLURM_ARRAY_TASK_COUNT is not"), std::string::npos);
    EXPECT_NE(usageError("", 3, {}).find("--shard-count needs"), std::string::npos);
    // It gave shard -4/4: accepted, no frames, exit 0.
    EXPECT_NE(usageError("", 0, {{"SLURM_ARRAY_TASK_ID", "1"}, {"SLURM_ARRAY_TASK_MIN", "5"}, {"SLURM_ARRAY_TASK_COUNT", "4"}})
                  .find("shard index -4 is negative"),
              std::string::npos);
}

TEST(Shard, SlurmStepArraysTakeTheTasksPlaceAndShardCountNeedsNoFlag)
{
    // --array=0-6:2: tasks 0, 2, 4, 6 are shards 0..3 of 4 (task 2 ran as 2/4, tasks 4 and 6 failed).
    for (int id : {0, 2, 4, 6}) {
        const Shard s = resolveShard("", 0, envOf({{"SLURM_ARRAY_TASK_ID", std::to_string(id)}, {"SLURM_ARRAY_TASK_MIN", "0"},
                                                   {"SLURM_ARRAY_TASK_STEP", "2"}, {"SLURM_ARRAY_TASK_COUNT", "4"}}));
        EXPECT_EQ(s.index, id / 2);
        EXPECT_EQ(s.count, 4);
    }
    EXPECT_NE(usageError("", 0, {{"SLURM_ARRAY_TASK_ID", "3"}, {"SLURM_ARRAY_TASK_STEP", "2"}, {"SLURM_ARRAY_TASK_COUNT", "4"}})
                  .find("multiple of SLURM_ARRAY_TASK_STEP 2"),
              std::string::npos);
    // --shard-count beside --shard was silently ignored.
    EXPECT_NE(usageError("1/3", 4, {}).find("not both"), std::string::npos);
}

TEST(Shard, JobsOfABatchIgnoreTheSchedulersVariables)
{
    ::setenv("SLURM_ARRAY_TASK_ID", "1", 1);
    ::setenv("SLURM_ARRAY_TASK_COUNT", "2", 1);
    {
        const SchedulerEnvironmentIgnored whole;
        EXPECT_TRUE(resolveShard("", 0).whole());
        EXPECT_EQ(resolveShard("", 0).source, "none");
    }
    EXPECT_EQ(resolveShard("", 0).index, 1);
    ::unsetenv("SLURM_ARRAY_TASK_ID");
    ::unsetenv("SLURM_ARRAY_TASK_COUNT");
}
