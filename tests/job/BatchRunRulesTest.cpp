// What batch and animate runs compare and hold: resume and merge compare the contents of the inputs, a manifest
// has one writer at a time, and merge and rewrites keep only entries that verify.
#include <gtest/gtest.h>

#include <chrono>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <sys/file.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "core/Error.h"
#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "job/JobList.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

void writeText(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }
json readJson(const std::string& path) { return json::parse(fileBytes(path)); }

const char* kAnim = R"({"version":1,"units":"bbox","frames":2,"graph":{"nodes":32,"k":6,"seed":0},
 "handles":[{"box":{"min":[-0.01,-0.01,-0.01],"max":[0.15,1.01,1.01]},"fixed":true},
            {"box":{"min":[0.85,-0.01,-0.01],"max":[1.01,1.01,1.01]},"pivot":[0.5,1.05,0.5],
             "keys":[{"frame":0},{"frame":1,"rotate":{"axis":[0,0,1],"degrees":30}}]}]})";

struct Fixture {
    TempDir dir;
    std::string model, spec;
    Fixture()
    {
        model = dir.file("in.ply");
        writeModel(model, 800);
        spec = dir.file("anim.json");
        writeText(spec, kAnim);
    }
    static void writeModel(const std::string& path, int count)
    {
        DemoModelOptions so;
        so.count = count;
        writePly(path, makeDemoModel("stripes", so));
    }
    int run(const std::string& args, std::string* log = nullptr) const
    {
        const int rc = runCli(args, dir.file("cli.log"));
        if (log) *log = fileBytes(dir.file("cli.log"));
        return rc;
    }
    int animate(const std::string& out, const std::string& extra = "", std::string* log = nullptr, const std::string& input = "") const
    {
        return run(msg("-q animate ", input.empty() ? model : input, " --spec ", spec, " -o ", out, " --stage1-only --nodes 32 ", extra), log);
    }
    std::string jobs(const std::string& list) const
    {
        writeText(dir.file("jobs.json"), list);
        return dir.file("jobs.json");
    }
    std::string toVdbJob(const std::string& output) const
    {
        return msg(R"({"kind":"to-vdb","input":")", model, R"(","output":")", output, R"(","args":["--cells","8"]})");
    }
};

std::set<int> doneFrames(const json& manifest)
{
    std::set<int> out;
    for (const json& e : manifest["entries"])
        if (e["status"] == "done") out.insert(e["frame"].get<int>());
    return out;
}

} // namespace

TEST(BatchRunRules, ResumeAndMergeCompareTheInputsContentsNotTheirPaths)
{
    Fixture fx;
    const std::string out = fx.dir.file("A");
    std::string log;
    ASSERT_EQ(fx.animate(out, "", &log), 0) << log;
    Fixture::writeModel(fx.model, 900); // another model at the same path: every frame again
    ASSERT_EQ(fx.animate(out, "", &log), 0) << log;
    EXPECT_NE(log.find("2 done, 0 resumed"), std::string::npos) << log;
    ASSERT_EQ(fx.animate(out, "", &log), 0) << log;
    EXPECT_NE(log.find("0 done, 2 resumed"), std::string::npos) << log;
    // Shards of one model spelled two ways merge; a shard of another model does not.
    const std::string m = fx.dir.file("M");
    ASSERT_EQ(fx.animate(m, "--shard 0/2", &log, fx.dir.file(".") + "/./in.ply"), 0) << log;
    ASSERT_EQ(fx.animate(m, "--shard 1/2"), 0);
    EXPECT_EQ(fx.run(msg("-q animate --merge ", m), &log), 0) << log;
    Fixture::writeModel(fx.model, 700);
    ASSERT_EQ(fx.animate(m, "--shard 1/2"), 0);
    EXPECT_EQ(fx.run(msg("-q animate --merge ", m), &log), 1);
    EXPECT_NE(log.find("settingsHash differs"), std::string::npos) << log;
}

TEST(BatchRunRules, ABatchJobWhoseInputChangedRunsAgain)
{
    Fixture fx;
    const std::string jobs = fx.jobs("{\"jobs\":[" + fx.toVdbJob("v0") + "]}");
    const std::string cmd = msg("-q batch ", jobs, " -o ", fx.dir.file("out"));
    std::string log;
    ASSERT_EQ(fx.run(cmd, &log), 0) << log;
    ASSERT_EQ(fx.run(cmd, &log), 0) << log;
    EXPECT_NE(log.find("0 done, 1 resumed"), std::string::npos) << log;
    Fixture::writeModel(fx.model, 900);
    ASSERT_EQ(fx.run(cmd, &log), 0) << log;
    EXPECT_NE(log.find("1 done, 0 resumed"), std::string::npos) << log;
}

TEST(BatchRunRules, ASecondRunOnOneManifestIsRefusedAtStart)
{
    Fixture fx;
    const std::string out = fx.dir.file("C");
    fs::create_directories(out);
    // The lock another run holds (flock: the kernel drops it with that process).
    const int fd = ::open((out + "/.manifest.json.lock").c_str(), O_RDWR | O_CREAT, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
    std::string log;
    EXPECT_EQ(fx.animate(out, "", &log), 1);
    EXPECT_NE(log.find("manifest.json: another run is writing it now"), std::string::npos) << log;
    EXPECT_EQ(fx.animate(out, "--shard 1/2", &log), 0) << log; // another manifest: runs beside it
    ::close(fd);
    EXPECT_EQ(fx.animate(out, "", &log), 0) << log;
    EXPECT_EQ(doneFrames(readJson(out + "/manifest.json")), (std::set<int>{0, 1}));
}

TEST(BatchRunRules, BatchMergeChecksThatAJobsFilesAreItsOwn)
{
    Fixture fx;
    const std::string jobs = fx.jobs("{\"jobs\":[" + fx.toVdbJob("v0") + "," + fx.toVdbJob("v1") + "]}");
    const std::string out = fx.dir.file("out");
    for (const char* s : {"0/2", "1/2"}) ASSERT_EQ(fx.run(msg("-q batch ", jobs, " -o ", out, " --shard ", s)), 0);
    std::string log;
    ASSERT_EQ(fx.run(msg("-q batch --merge ", out), &log), 0) << log;
    // Job 1's output gone; its entry now lists a copy of job 0's file outside v1, with the copy's true size and digest.
    json m = readJson(out + "/manifest.shard-1.json");
    json& file = m["entries"][0]["files"][0];
    const std::string copy = "stray.vdb";
    fs::copy_file(out + "/" + file["path"].get<std::string>(), out + "/" + copy);
    fs::remove_all(out + "/v1");
    file["path"] = copy;
    writeText(out + "/manifest.shard-1.json", m.dump());
    EXPECT_EQ(fx.run(msg("-q batch --merge ", out), &log), 1);
    EXPECT_NE(log.find("stray.vdb: is not a file of job 1"), std::string::npos) << log;
}

TEST(BatchRunRules, MergeKeepsACompleteManifestAndRewritesCarryOnlyVerifiedEntries)
{
    Fixture fx;
    const std::string out = fx.dir.file("W");
    std::string log;
    ASSERT_EQ(fx.animate(out, "--shard 0/2"), 0);
    ASSERT_EQ(fx.animate(out), 0);
    EXPECT_EQ(fx.run(msg("-q animate --merge ", out), &log), 0) << log; // was rc 1, manifest.json cut to frame 0
    EXPECT_EQ(doneFrames(readJson(out + "/manifest.json")), (std::set<int>{0, 1}));
    // A frame whose file is gone is not carried as done by a run over other frames.
    fs::remove(out + "/frames/baseline.0000.ply");
    ASSERT_EQ(fx.animate(out, "--frames 1-1", &log), 0) << log;
    EXPECT_EQ(doneFrames(readJson(out + "/manifest.json")), (std::set<int>{1}));
}

TEST(BatchRunRules, ManyJobsArePathCheckedWithoutAFileSystemWalkPerPair)
{
    TempDir dir;
    std::vector<BatchJob> jobs(800);
    for (std::size_t i = 0; i < jobs.size(); ++i) {
        jobs[i].kind = &jobKinds().front();
        jobs[i].input = dir.file(msg("in/deep/er/still/model", i, ".ply"));
        jobs[i].output = msg("out", i);
        jobs[i].reads = {jobs[i].input, dir.file("spec.json")};
    }
    const auto start = std::chrono::steady_clock::now();
    EXPECT_EQ(checkJobPaths(jobs, dir.file("runs"), dir.file("jobs.json")).size(), jobs.size());
    // One weakly_canonical per pair took ~70 s for 800 jobs; once per path takes milliseconds.
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 5.0);
    // The refusals are the same: an output holding an earlier job's input.
    jobs[5].output = "in";
    jobs[2].input = dir.file("runs/in/x.ply");
    jobs[2].reads = {jobs[2].input};
    EXPECT_NE(inputErrorMessage([&] { checkJobPaths(jobs, dir.file("runs"), dir.file("jobs.json")); }).find("job 5: \"output\" in would overwrite the input of job 2"),
              std::string::npos);
}
