// A job list and a manifest are data someone else may have written: every path they name must
// stay inside the output folder, and merge and resume verify what they take from a manifest.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <sys/stat.h>

#include <nlohmann/json.hpp>

#include "job/AnimateJob.h"
#include "job/JobList.h"
#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

void writeText(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

const char* kAnim = R"({"version":1,"units":"bbox","frames":2,"graph":{"nodes":32,"k":6,"seed":0},
 "handles":[{"box":{"min":[-0.01,-0.01,-0.01],"max":[0.15,1.01,1.01]},"fixed":true},
            {"box":{"min":[0.85,-0.01,-0.01],"max":[1.01,1.01,1.01]},"pivot":[0.5,1.05,0.5],
             "keys":[{"frame":0},{"frame":1,"rotate":{"axis":[0,0,1],"degrees":30}}]}]})";

const std::string kBend = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json";

struct Fixture {
    TempDir dir;
    std::string model, spec;
    Fixture()
    {
        DemoModelOptions so;
        so.count = 800;
        model = dir.file("in.ply");
        writePly(model, makeDemoModel("stripes", so));
        spec = dir.file("anim.json");
        writeText(spec, kAnim);
    }
    /// Run a batch of one job list; returns the exit code, the log in `log`.
    int batch(const std::string& jobs, const std::string& out, std::string& log) const
    {
        writeText(dir.file("jobs.json"), jobs);
        const int rc = runCli(msg("-q batch ", dir.file("jobs.json"), " -o ", out), dir.file("batch.log"));
        log = fileBytes(dir.file("batch.log"));
        return rc;
    }
    std::string toVdbJob(const std::string& output, const std::string& args = "") const
    {
        return msg(R"({"kind":"to-vdb","input":")", model, R"(","output":")", output, R"(","args":["--cells","8")", args, "]}");
    }
    int animate(const std::string& out, const std::string& extra = "") const
    {
        return runCli(msg("-q animate ", model, " --spec ", spec, " -o ", out, " --stage1-only --nodes 32 ", extra),
                      dir.file("animate.log"));
    }
};

/// Files in a folder tree (none outside what a test expects may appear).
std::size_t filesUnder(const fs::path& p)
{
    std::size_t n = 0;
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(p, ec); it != fs::recursive_directory_iterator(); ++it) n += 1;
    return n;
}

} // namespace

TEST(BatchSafety, OutputsOutsideTheFolderAreRefusedBeforeAnyJobRuns)
{
    Fixture fx;
    const std::string out = fx.dir.file("runs");
    fs::create_directories(fx.dir.file("elsewhere"));
    writeText(fx.dir.file("elsewhere/user.vdb"), "the user's file");
    fs::create_directories(out);
    fs::create_directory_symlink(fx.dir.file("elsewhere"), fx.dir.file("runs/link"));
    struct Case {
        std::string job, message;
    };
    const std::vector<Case> cases = {
        {fx.toVdbJob(fx.dir.file("elsewhere/user.vdb")), "is an absolute path"},
        {fx.toVdbJob("../elsewhere/user.vdb"), "climbs out of the output folder"},
        {fx.toVdbJob("link/user.vdb"), "is a symbolic link"},
        {fx.toVdbJob("a.vdb", R"(,"--spec",")" + fx.dir.file("runs/a.vdb") + "\""), "would overwrite its own input"},
        {fx.toVdbJob("manifest.json"), "is the name of a batch manifest"},
        {R"({"kind":"from-vdb","input":"x.vdb","output":"x.ply","args":["--report",")" + fx.dir.file("elsewhere/r.json") + R"("]})",
         "may not name an output (--report)"},
        {R"({"kind":"from-vdb","input":"x.vdb","output":"x.ply","args":["--report=r.json"]})", "may not name an output (--report=r.json)"},
        {R"({"kind":"animate","input":"x.ply","output":"a","args":["--merge",")" + fx.dir.file("elsewhere") + R"("]})",
         "may not name an output (--merge"},
        {R"({"kind":"deform","input":"x.ply","output":"d","args":["--output","y"]})", "may not name an output (--output)"},
    };
    for (const Case& c : cases) {
        std::string log;
        EXPECT_EQ(fx.batch(R"({"jobs":[)" + fx.toVdbJob("first.vdb") + "," + c.job + "]}", out, log), 1) << c.job;
        EXPECT_NE(log.find(c.message), std::string::npos) << c.job << "\n" << log;
        EXPECT_NE(log.find("job 1"), std::string::npos) << log;
        EXPECT_FALSE(fs::exists(fx.dir.file("runs/first.vdb"))) << "a job ran before the list was checked: " << c.job;
    }
    EXPECT_EQ(fileBytes(fx.dir.file("elsewhere/user.vdb")), "the user's file");
    EXPECT_EQ(filesUnder(fx.dir.file("elsewhere")), 1u);
    EXPECT_EQ(filesUnder(out), 1u); // only the symlink
}

TEST(BatchSafety, OutputsMayNotCollideOrOverwriteTheJobListOrAnInput)
{
    Fixture fx;
    const std::string out = fx.dir.file("runs");
    std::string log;
    EXPECT_EQ(fx.batch(R"({"jobs":[)" + fx.toVdbJob("same.vdb") + "," + fx.toVdbJob("same.vdb") + "]}", out, log), 1);
    EXPECT_NE(log.find("is also the output of job 0"), std::string::npos) << log;
    EXPECT_EQ(fx.batch(R"({"jobs":[)" + fx.toVdbJob("d") + "," + fx.toVdbJob("d/x.vdb") + "]}", out, log), 1);
    EXPECT_NE(log.find("is also the output of job 0"), std::string::npos) << log;
    // The job list inside the output folder, and a job aimed at it.
    fs::create_directories(out);
    const std::string jobs = msg(R"({"jobs":[)", fx.toVdbJob("jobs.json"), "]}");
    writeText(out + "/jobs.json", jobs);
    EXPECT_EQ(runCli(msg("batch ", out, "/jobs.json -o ", out), fx.dir.file("l.log")), 1);
    EXPECT_NE(fileBytes(fx.dir.file("l.log")).find("would overwrite the job list"), std::string::npos) << fileBytes(fx.dir.file("l.log"));
    EXPECT_EQ(fileBytes(out + "/jobs.json"), jobs);
    // A later job's input under an earlier output is a chain; under a later output it would be lost.
    const std::string chained = msg(R"({"kind":"to-vdb","input":")", out, R"(/a.ply","output":"b.vdb"})");
    EXPECT_EQ(fx.batch(R"({"jobs":[)" + chained + "," + fx.toVdbJob("a.ply") + "]}", out, log), 1);
    EXPECT_NE(log.find("job 1: \"output\" a.ply would overwrite the input of job 0"), std::string::npos) << log;
    const std::vector<BatchJob> chain = parseJobList(R"({"jobs":[)" + fx.toVdbJob("a.ply") + "," + chained + "]}", "j.json");
    EXPECT_NO_THROW(checkJobPaths(chain, out, fx.dir.file("jobs.json")));
}

TEST(BatchSafety, JobListParserNamesTheFileAndTheJob)
{
    for (const auto& [text, message] : std::vector<std::pair<std::string, std::string>>{
             {"[1,2]", "needs \"jobs\""},
             {R"({"jobs":[{"kind":5,"input":"a","output":"b"}]})", "\"kind\" must be one of deform, animate, to-vdb, from-vdb (got 5)"},
             {R"({"jobs":[{"kind":"deform","input":7,"output":"b"}]})", "job 0: needs \"input\""},
             {R"({"jobs":[{"kind":"deform","input":"a","output":"b","args":"--x"}]})", "\"args\" must be an array of strings"},
             {R"({"jobs":[{"kind":"deform","input":"a","output":"b"},{"kind":"deform","input":"a","output":"c","args":["-o","x"]}]})",
              "j.json: job 1: \"args\" may not name an output (-o)"}}) {
        const std::string m = inputErrorMessage([&] { parseJobList(text, "j.json"); });
        EXPECT_NE(m.find(message), std::string::npos) << text << "\n" << m;
        EXPECT_EQ(m.rfind("j.json", 0), 0u) << m;
    }
    const std::vector<BatchJob> jobs = parseJobList(R"({"jobs":[{"kind":"deform","input":"a.ply","output":"b","args":["--spec=s.json"]}]})", "j");
    EXPECT_EQ(jobs[0].reads, (std::vector<std::string>{"a.ply", "s.json"}));
}

TEST(AnimateSafety, InputsInsideTheOutputsAreRefused)
{
    Fixture fx;
    const std::string out = fx.dir.file("a");
    fs::create_directories(out + "/frames");
    fs::copy_file(fx.model, out + "/frames/deformed.0000.ply");
    EXPECT_EQ(runCli(msg("animate ", out, "/frames/deformed.0000.ply --spec ", fx.spec, " -o ", out), fx.dir.file("1.log")), 1);
    EXPECT_NE(fileBytes(fx.dir.file("1.log")).find("which animate -o"), std::string::npos) << fileBytes(fx.dir.file("1.log"));
    EXPECT_EQ(fileBytes(out + "/frames/deformed.0000.ply"), fileBytes(fx.model));
    writeText(out + "/manifest.json", kAnim);
    EXPECT_EQ(runCli(msg("animate ", fx.model, " --spec ", out, "/manifest.json -o ", out), fx.dir.file("2.log")), 1);
    EXPECT_NE(fileBytes(fx.dir.file("2.log")).find("is a manifest of the output folder"), std::string::npos) << fileBytes(fx.dir.file("2.log"));
    // A run that fails before its first frame leaves no empty folders.
    EXPECT_EQ(runCli(msg("animate ", fx.dir.file("missing.ply"), " --spec ", fx.spec, " -o ", fx.dir.file("b"), " --vdb"), fx.dir.file("3.log")), 1);
    EXPECT_FALSE(fs::exists(fx.dir.file("b")));
}

TEST(AnimateSafety, MergeVerifiesEveryListedFileAndNamesTheFrame)
{
    Fixture fx;
    const std::string out = fx.dir.file("s");
    ASSERT_EQ(fx.animate(out, "--shard 0/2"), 0) << fileBytes(fx.dir.file("animate.log"));
    ASSERT_EQ(fx.animate(out, "--shard 1/2"), 0) << fileBytes(fx.dir.file("animate.log"));
    ASSERT_EQ(runCli(msg("animate --merge ", out, " --zip"), fx.dir.file("m0.log")), 0) << fileBytes(fx.dir.file("m0.log"));
    EXPECT_TRUE(fs::exists(out + "/sequence.zip"));
    const std::string good = fileBytes(out + "/manifest.shard-1.json");
    auto forge = [&](const std::function<void(json&)>& edit) {
        json m = json::parse(good);
        edit(m["entries"][0]);
        writeText(out + "/manifest.shard-1.json", m.dump());
        const int rc = runCli(msg("animate --merge ", out), fx.dir.file("m.log"));
        return std::make_pair(rc, fileBytes(fx.dir.file("m.log")));
    };
    const std::string frame1 = frameFile("baseline", 1);
    const std::vector<std::pair<std::function<void(json&)>, std::string>> cases = {
        {[](json& e) { e["files"][0]["fnv1a64"] = "0000000000000000"; }, "its digest differs"},
        {[](json& e) { e["files"][0]["bytes"] = 12; }, "the manifest says 12"},
        {[](json& e) { e["files"][0]["path"] = "../in.ply"; }, "climbs out"},
        {[&](json& e) { e["files"][0]["path"] = fx.model; }, "absolute path"},
        {[](json& e) { e["files"][0]["path"] = frameFile("baseline", 0); }, "is not a file of frame 1"},
        {[](json& e) { e["frame"] = "one"; }, "not a manifest of splatwarp"},
    };
    for (const auto& [edit, message] : cases) {
        const auto [rc, log] = forge(edit);
        EXPECT_EQ(rc, 1) << message;
        EXPECT_NE(log.find(message), std::string::npos) << message << "\n" << log;
    }
    // A forged all-done shard whose frame is absent.
    forge([](json&) {});
    fs::remove(out + "/" + frame1);
    const auto [rc, log] = forge([](json&) {});
    EXPECT_EQ(rc, 1);
    EXPECT_NE(log.find("frame 1: merge: " + frame1 + ": is missing"), std::string::npos) << log;
}

TEST(AnimateSafety, ResumeRecomputesAnEntryThatDoesNotVerify)
{
    Fixture fx;
    const std::string out = fx.dir.file("r");
    ASSERT_EQ(fx.animate(out), 0);
    const std::string frame1 = fileBytes(out + "/" + frameFile("baseline", 1));
    // Frame 1's entry edited to point at frame 0's file (which exists and verifies).
    json m = json::parse(fileBytes(out + "/manifest.json"));
    m["entries"][1]["files"] = m["entries"][0]["files"];
    writeText(out + "/manifest.json", m.dump());
    fs::remove(out + "/" + frameFile("baseline", 1));
    ASSERT_EQ(fx.animate(out), 0);
    EXPECT_NE(fileBytes(fx.dir.file("animate.log")).find("1 done, 1 resumed"), std::string::npos);
    EXPECT_EQ(fileBytes(out + "/" + frameFile("baseline", 1)), frame1);
}

TEST(AnimateSafety, MergeAndZipRefuseASymlinkedFrame)
{
    Fixture fx;
    const std::string out = fx.dir.file("z");
    ASSERT_EQ(fx.animate(out, "--shard 0/2"), 0);
    ASSERT_EQ(fx.animate(out, "--shard 1/2"), 0);
    const std::string frame1 = out + "/" + frameFile("baseline", 1);
    fs::rename(frame1, fx.dir.file("moved.ply"));
    fs::create_symlink(fx.dir.file("moved.ply"), frame1); // same bytes, but outside DIR
    EXPECT_EQ(runCli(msg("animate --merge ", out, " --zip"), fx.dir.file("m.log")), 1);
    EXPECT_NE(fileBytes(fx.dir.file("m.log")).find(frameFile("baseline", 1) + " is a symbolic link"), std::string::npos)
        << fileBytes(fx.dir.file("m.log"));
    EXPECT_FALSE(fs::exists(out + "/sequence.zip"));
}

TEST(BatchSafety, NestedOutputsAreWrittenWhereTheyAreNamed)
{
    // Every part of "output" counts, also below the first folder that does not exist yet.
    Fixture fx;
    const std::string out = fx.dir.file("runs");
    std::string log;
    ASSERT_EQ(fx.batch(R"({"jobs":[)" + fx.toVdbJob("sub/s.vdb") + "," + fx.toVdbJob("deep/er/t.vdb") + "]}", out, log), 0) << log;
    EXPECT_TRUE(fs::is_regular_file(out + "/sub/s.vdb"));
    EXPECT_TRUE(fs::is_regular_file(out + "/deep/er/t.vdb"));
    const json m = json::parse(fileBytes(out + "/manifest.json"));
    EXPECT_EQ(m["entries"][0]["files"][0]["path"], "sub/s.vdb") << m.dump();
    // Two files in one new folder are two outputs, not one.
    ASSERT_EQ(fx.batch(R"({"jobs":[)" + fx.toVdbJob("v/a.vdb") + "," + fx.toVdbJob("v/b.vdb") + "]}", out, log), 0) << log;
    EXPECT_EQ(fx.batch(R"({"jobs":[)" + fx.toVdbJob("first.vdb") + "," + fx.toVdbJob("a/../b.vdb") + "]}", out, log), 1);
    EXPECT_NE(log.find("climbs out"), std::string::npos) << log;
}

TEST(BatchSafety, ARecipeFileIsAnInput)
{
    Fixture fx;
    const std::string out = fx.dir.file("runs");
    fs::create_directories(out + "/d");
    const std::string recipe = R"({"recipe":"mine","steps":[{"step":"stage1"},{"step":"stage2","iterations":3}]})";
    writeText(out + "/d/report.json", recipe);
    std::string log;
    const std::string job = msg(R"({"kind":"deform","input":")", fx.model, R"(","output":"d","args":["--spec",")", fx.spec,
                                R"(","--recipe",")", out, R"(/d/report.json"]})");
    EXPECT_EQ(fx.batch(R"({"jobs":[)" + job + "]}", out, log), 1);
    EXPECT_NE(log.find("would overwrite its own input"), std::string::npos) << log;
    // The same from deform itself, refused before any work; the built-in names are no files.
    EXPECT_EQ(runCli(msg("deform ", fx.model, " --spec ", kBend, " --recipe ", out, "/d/report.json -o ", out, "/d"),
                     fx.dir.file("d.log")), 1);
    EXPECT_NE(fileBytes(fx.dir.file("d.log")).find("is also an input"), std::string::npos) << fileBytes(fx.dir.file("d.log"));
    EXPECT_EQ(fileBytes(out + "/d/report.json"), recipe);
    EXPECT_EQ(parseJobList(R"({"jobs":[{"kind":"deform","input":"a.ply","output":"b","args":["--recipe","paper"]}]})", "j")[0].reads,
              (std::vector<std::string>{"a.ply"}));
}

TEST(DeformSafety, AStage1OnlyRunNeverRemovesItsInput)
{
    // --stage1-only removes an earlier run's deformed.ply; not when that file is what it reads.
    Fixture fx;
    const std::string out = fx.dir.file("t");
    fs::create_directories(out);
    fs::copy_file(fx.model, out + "/deformed.ply");
    EXPECT_EQ(runCli(msg("deform ", out, "/deformed.ply --spec ", kBend, " -o ", out, " --stage1-only"), fx.dir.file("1.log")), 1);
    EXPECT_NE(fileBytes(fx.dir.file("1.log")).find("is an input of this command"), std::string::npos) << fileBytes(fx.dir.file("1.log"));
    EXPECT_EQ(fileBytes(out + "/deformed.ply"), fileBytes(fx.model));
    EXPECT_FALSE(fs::exists(out + "/baseline.ply"));
}

TEST(AnimateSafety, ASymlinkedFolderOrManifestIsRefusedBeforeTheFirstFrame)
{
    Fixture fx;
    fs::create_directories(fx.dir.file("outside"));
    const std::string a = fx.dir.file("a");
    fs::create_directories(a);
    fs::create_directory_symlink(fx.dir.file("outside"), a + "/frames");
    EXPECT_EQ(fx.animate(a), 1);
    EXPECT_NE(fileBytes(fx.dir.file("animate.log")).find("frames: is a symbolic link"), std::string::npos)
        << fileBytes(fx.dir.file("animate.log"));
    EXPECT_EQ(filesUnder(fx.dir.file("outside")), 0u);
    const std::string b = fx.dir.file("b");
    fs::create_directories(b);
    fs::create_symlink(fx.dir.file("outside/m.json"), b + "/manifest.json");
    EXPECT_EQ(fx.animate(b), 1);
    EXPECT_FALSE(fs::exists(b + "/frames")) << "a frame ran before the manifest was checked";
    EXPECT_EQ(filesUnder(fx.dir.file("outside")), 0u);
}

TEST(AnimateSafety, ADoneEntryListingNoFilesIsRecomputed)
{
    Fixture fx;
    const std::string out = fx.dir.file("r");
    ASSERT_EQ(fx.animate(out), 0);
    json m = json::parse(fileBytes(out + "/manifest.json"));
    m["entries"][1]["files"] = json::array();
    writeText(out + "/manifest.json", m.dump());
    fs::remove(out + "/" + frameFile("baseline", 1));
    ASSERT_EQ(fx.animate(out), 0);
    EXPECT_NE(fileBytes(fx.dir.file("animate.log")).find("1 done, 1 resumed"), std::string::npos) << fileBytes(fx.dir.file("animate.log"));
    EXPECT_TRUE(fs::exists(out + "/" + frameFile("baseline", 1)));
}

TEST(BatchSafety, AnimateJobsRunAllTheirFramesUnderASchedulersArray)
{
    Fixture fx;
    const std::string job = msg(R"({"kind":"animate","input":")", fx.model, R"(","output":"anim0","args":["--spec",")", fx.spec,
                                R"(","--stage1-only","--nodes","32"]})");
    // Before, the job took the batch's SLURM variables: shard 0/2 of its own frames, manifest.shard-0.json.
    ::setenv("SLURM_ARRAY_TASK_ID", "0", 1);
    ::setenv("SLURM_ARRAY_TASK_COUNT", "2", 1);
    std::string log;
    const int rc = fx.batch("{\"jobs\":[" + job + "]}", fx.dir.file("out"), log);
    ::unsetenv("SLURM_ARRAY_TASK_ID");
    ::unsetenv("SLURM_ARRAY_TASK_COUNT");
    ASSERT_EQ(rc, 0) << log;
    EXPECT_TRUE(fs::exists(fx.dir.file("out/manifest.shard-0.json"))); // the batch is the shard
    EXPECT_FALSE(fs::exists(fx.dir.file("out/anim0/manifest.shard-0.json")));
    const json m = json::parse(fileBytes(fx.dir.file("out/anim0/manifest.json")));
    ASSERT_EQ(m["entries"].size(), 2u);
    for (const json& e : m["entries"]) EXPECT_EQ(e["status"], "done");
    // A job may not ask for a shard of its own frames.
    EXPECT_EQ(fx.batch(R"({"jobs":[{"kind":"animate","input":"a.ply","output":"x","args":["--shard","0/2"]}]})", fx.dir.file("out2"), log), 1);
    EXPECT_NE(log.find("batch runs each job whole"), std::string::npos) << log;
}

TEST(BatchSafety, JobListRefusesHelpAndUnknownKeys)
{
    auto error = [](const std::string& text) { return inputErrorMessage([&] { parseJobList(text, "jobs.json"); }); };
    EXPECT_NE(error(R"({"jobs":[{"kind":"deform","input":"a.ply","output":"x","args":["--help"]}]})")
                  .find("jobs.json: job 0: \"args\" may not hold --help"),
              std::string::npos);
    EXPECT_NE(error(R"({"jobs":[{"kind":"deform","input":"a.ply","output":"x","args":["-h"]}]})").find("may not hold -h"), std::string::npos);
    EXPECT_NE(error(R"({"jobs":[{"kind":"deform","input":"a.ply","output":"x"},{"kind":"deform","input":"a.ply","output":"y","arg":["-q"]}]})")
                  .find("jobs.json: job 1: unknown key \"arg\""),
              std::string::npos);
}
