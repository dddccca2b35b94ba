#include <gtest/gtest.h>

#include <chrono>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <signal.h>
#include <sstream>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

#include "job/AnimateJob.h"
#include "deform/AnimSpec.h"
#include "io/GaussianIO.h"
#include "demo/DemoModels.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

/// A 3-frame bend of a small stripes bar with few iterations: a frame takes well under a second.
const char* kAnim = R"({"version":1,"units":"bbox","frames":3,"graph":{"nodes":48,"k":6,"seed":0},
 "handles":[{"box":{"min":[-0.01,-0.01,-0.01],"max":[0.15,1.01,1.01]},"fixed":true},
            {"box":{"min":[0.85,-0.01,-0.01],"max":[1.01,1.01,1.01]},"pivot":[0.5,1.05,0.5],
             "keys":[{"frame":0},{"frame":2,"rotate":{"axis":[0,0,1],"degrees":60},"translate":[0,0.05,0]}]}]})";
const char* kFlags = "--iterations 3 --cells 12 --eval-points 3000";

std::string readBytes(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

void writeText(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

struct Fixture {
    TempDir dir;
    std::string model, spec;
    Fixture()
    {
        DemoModelOptions so;
        so.count = 1500;
        model = dir.file("in.ply");
        writePly(model, makeDemoModel("stripes", so));
        spec = dir.file("anim.json");
        writeText(spec, kAnim);
    }
    int animate(const std::string& out, const std::string& extra = "") const
    {
        return runCli(msg("-q animate ", model, " --spec ", spec, " -o ", dir.file(out), " ", kFlags, " ", extra),
                      dir.file(out + ".log"));
    }
    std::string frame(const std::string& out, int f) const { return readBytes(dir.file(out) + "/" + frameFile("deformed", f)); }
};

json readJson(const std::string& path)
{
    std::ifstream in(path);
    return json::parse(in);
}

} // namespace

TEST(AnimateJob, FrameEqualsDeformWithItsSpecAndShardsEqualTheWholeRun)
{
    Fixture fx;
    ASSERT_EQ(fx.animate("whole", "--vdb"), 0) << readBytes(fx.dir.file("whole.log"));
    // Frame 1 (between keys, slerped) written as a plain spec and run through `deform`.
    const AnimSpec anim = parseAnimSpec(kAnim, "anim.json");
    writeText(fx.dir.file("frame1.json"), frameSpecJson(anim, 1).dump(2));
    ASSERT_EQ(runCli(msg("-q deform ", fx.model, " --spec ", fx.dir.file("frame1.json"), " -o ", fx.dir.file("d1"), " ", kFlags, " --vdb")), 0);
    const std::string deformed = readBytes(fx.dir.file("d1/deformed.ply"));
    ASSERT_FALSE(deformed.empty());
    EXPECT_TRUE(fx.frame("whole", 1) == deformed) << "frame 1 differs from deform with its spec";
    // A .vdb names the model it samples in its metadata ("source"), so frames and deform's field
    // differ there; a rerun's are the same bytes (VdbExport.CliToVdbAndExternalTools).
    EXPECT_GT(fs::file_size(fx.dir.file("whole/vdb/field.0001.vdb")), 1000u);
    EXPECT_FALSE(fx.frame("whole", 0) == fx.frame("whole", 2));

    // Two shards into one folder, merged: every frame byte-equal to the whole run.
    ASSERT_EQ(fx.animate("sharded", "--shard 1/2"), 0);
    ASSERT_EQ(fx.animate("sharded", "--shard 0/2"), 0);
    EXPECT_TRUE(fs::exists(fx.dir.file("sharded/manifest.shard-1.json")));
    EXPECT_EQ(runCli(msg("-q animate --merge ", fx.dir.file("sharded"), " --zip")), 0);
    for (int f = 0; f < 3; ++f) EXPECT_TRUE(fx.frame("sharded", f) == fx.frame("whole", f)) << f;
    const json m = readJson(fx.dir.file("sharded/manifest.json"));
    EXPECT_EQ(m["entries"].size(), 3u);
    EXPECT_TRUE(m["missing"].empty());
    EXPECT_EQ(m["entries"][1]["files"][0]["path"], "frames/deformed.0001.ply");
    EXPECT_EQ(m["entries"][1]["files"][0]["bytes"].get<std::size_t>(), fx.frame("whole", 1).size());
    EXPECT_TRUE(m["entries"][2]["fieldError"]["stage2"].contains("opacity"));
    EXPECT_EQ(m["specHash"], fnv1a64(kAnim));
    EXPECT_GT(fs::file_size(fx.dir.file("sharded/sequence.zip")),
              fx.frame("whole", 0).size() + fx.frame("whole", 1).size() + fx.frame("whole", 2).size());
}

TEST(AnimateJob, ResumeRedoesOnlyFramesWhoseFilesOrEntriesAreMissing)
{
    Fixture fx;
    ASSERT_EQ(fx.animate("out"), 0);
    const std::string manifestPath = fx.dir.file("out/manifest.json");
    const std::string before = fx.frame("out", 2);
    // A kill during frame 2: its file may be there but its entry is not.
    json m = readJson(manifestPath);
    m["entries"].erase(2);
    writeText(manifestPath, m.dump());
    // Frame 0's file was damaged afterwards: its bytes no longer match the entry.
    writeText(fx.dir.file("out/") + frameFile("deformed", 0), "truncated");
    ASSERT_EQ(fx.animate("out"), 0);
    const std::string log = readBytes(fx.dir.file("out.log"));
    EXPECT_NE(log.find("2 done, 1 resumed, 0 failed"), std::string::npos) << log;
    const json after = readJson(manifestPath);
    ASSERT_EQ(after["entries"].size(), 3u);
    EXPECT_TRUE(fx.frame("out", 2) == before);
    EXPECT_GT(fs::file_size(fx.dir.file("out/") + frameFile("deformed", 0)), 100u);
    // Rerun without changes: nothing is computed (the stdout summary counts it).
    ASSERT_EQ(runCli(msg("-q animate ", fx.model, " --spec ", fx.spec, " -o ", fx.dir.file("out"), " ", kFlags), fx.dir.file("again.log")), 0);
    EXPECT_NE(readBytes(fx.dir.file("again.log")).find("0 done, 3 resumed, 0 failed"), std::string::npos)
        << readBytes(fx.dir.file("again.log"));
    // Different settings never reuse frames.
    ASSERT_EQ(runCli(msg("-q animate ", fx.model, " --spec ", fx.spec, " -o ", fx.dir.file("out"), " ", kFlags,
                         " --frames 1-1 --boundary-weight 5"), fx.dir.file("changed.log")), 0);
    EXPECT_NE(readBytes(fx.dir.file("changed.log")).find("1 done, 0 resumed"), std::string::npos);
    // Each flag added to the flags of the run before (which differs from it by that flag alone).
    std::string flags = msg(kFlags, " --frames 2-2");
    ASSERT_EQ(runCli(msg("-q animate ", fx.model, " --spec ", fx.spec, " -o ", fx.dir.file("out"), " ", flags)), 0);
    for (const char* flag : {"--stall-tolerance 0.5", "--max-mean-step 0.2", "--drop-invalid", "--warm-start",
                             "--fine-cells auto", "--stage1-shape polar",
                             "--endpoint-sigmas 1", "--keep regions", "--validated-split off"}) {
        flags += msg(" ", flag);
        ASSERT_EQ(runCli(msg("-q animate ", fx.model, " --spec ", fx.spec, " -o ", fx.dir.file("out"), " ", flags),
                         fx.dir.file("flag.log")), 0) << flags;
        EXPECT_NE(readBytes(fx.dir.file("flag.log")).find("1 done, 0 resumed"), std::string::npos) << flag;
    }
}

TEST(AnimateJob, WarmStartKeepsItsBytesWhateverTheShardsTheRangeOrAResume)
{
    Fixture fx;
    // Four frames that all bend (frame 0 too, so the pair (0, 1) has a fit to carry).
    std::string four = std::string(kAnim).replace(std::string(kAnim).find("\"frames\":3"), 10, "\"frames\":4");
    four.replace(four.find("{\"frame\":0}"), 11, R"({"frame":0,"rotate":{"axis":[0,0,1],"degrees":20}})");
    four.replace(four.find("\"frame\":2,"), 10, "\"frame\":3,");
    const std::string spec = fx.dir.file("anim4.json");
    writeText(spec, four);
    auto animate = [&](const std::string& out, const std::string& extra) {
        // No split: a frame whose split adds Gaussians starts cold, and this test needs warm ones.
        return runCli(msg("-q animate ", fx.model, " --spec ", spec, " -o ", fx.dir.file(out), " ", kFlags,
                          " --curve-split off --validated-split off ", extra),
                      fx.dir.file(out + ".log"));
    };
    ASSERT_EQ(animate("cold", ""), 0) << readBytes(fx.dir.file("cold.log"));
    ASSERT_EQ(animate("warm", "--warm-start"), 0) << readBytes(fx.dir.file("warm.log"));
    // Even frames start cold (deform's bytes), odd ones from the even frame's fit unless that start
    // is far above the even frame's fitted energy; the manifest says which.
    const json whole = readJson(fx.dir.file("warm/manifest.json"));
    std::map<int, json> entry;
    for (const json& e : whole["entries"]) entry[e["frame"].get<int>()] = e;
    for (int f : {0, 2}) {
        EXPECT_TRUE(fx.frame("warm", f) == fx.frame("cold", f)) << f;
        EXPECT_EQ(entry[f]["start"], "cold") << f;
    }
    for (int f : {1, 3}) {
        const json& w = entry[f]["warmStart"];
        const bool warm = w["energy"].get<double>() <= w["limit"].get<double>();
        EXPECT_EQ(entry[f]["start"], warm ? "warm" : "cold") << f;
        EXPECT_EQ(fx.frame("warm", f) == fx.frame("cold", f), !warm) << f;
    }
    EXPECT_EQ(entry[3]["start"], "warm"); // so the shard, range and resume checks below see a warm frame
    EXPECT_EQ(whole["settings"]["warmStart"], 2);
    EXPECT_NE(whole["settingsHash"], readJson(fx.dir.file("cold/manifest.json"))["settingsHash"]);

    // Two shards take contiguous pairs; merged, every frame equals the one-process run.
    ASSERT_EQ(animate("sharded", "--warm-start --shard 1/2"), 0);
    ASSERT_EQ(animate("sharded", "--warm-start --shard 0/2"), 0);
    EXPECT_EQ(readJson(fx.dir.file("sharded/manifest.shard-0.json"))["entries"].size(), 2u);
    EXPECT_EQ(readJson(fx.dir.file("sharded/manifest.shard-1.json"))["entries"][0]["frame"], 2);
    EXPECT_EQ(runCli(msg("-q animate --merge ", fx.dir.file("sharded"))), 0);
    for (int f = 0; f < 4; ++f) EXPECT_TRUE(fx.frame("sharded", f) == fx.frame("warm", f)) << f;

    // A range starting at an odd frame recomputes the frame before without writing it.
    ASSERT_EQ(animate("range", "--warm-start --frames 3-3"), 0);
    EXPECT_TRUE(fx.frame("range", 3) == fx.frame("warm", 3));
    EXPECT_FALSE(fs::exists(fx.dir.file("range/") + frameFile("deformed", 2)));

    // Resume: an odd frame killed before its entry was written is redone from its resumed predecessor.
    json m = whole;
    m["entries"].erase(3);
    writeText(fx.dir.file("warm/manifest.json"), m.dump());
    fs::remove(fx.dir.file("warm/") + frameFile("deformed", 3));
    ASSERT_EQ(animate("warm", "--warm-start"), 0);
    EXPECT_NE(readBytes(fx.dir.file("warm.log")).find("1 done, 3 resumed, 0 failed"), std::string::npos)
        << readBytes(fx.dir.file("warm.log"));
    EXPECT_TRUE(fx.frame("warm", 3) == fx.frame("sharded", 3));
    EXPECT_EQ(animate("excl", "--warm-start --stage1-only"), 2);
}

namespace {

/// argv for `splatwarp animate` of fx's model and `spec` into `out` (kFlags split on spaces).
std::vector<std::string> animateArgs(const Fixture& fx, const std::string& spec, const std::string& out)
{
    std::vector<std::string> args = {SPLATWARP_CLI, "animate", fx.model, "--spec", spec, "-o", out};
    std::istringstream flags(kFlags);
    for (std::string f; flags >> f;) args.push_back(f);
    return args;
}

/// Start the CLI (args[0]) as a child process with stdout and stderr in `log`; returns its pid.
pid_t spawnCli(const std::vector<std::string>& args, const std::string& log)
{
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const pid_t pid = fork();
    if (pid == 0) {
        if (!freopen(log.c_str(), "w", stdout) || dup2(fileno(stdout), 2) < 0) _exit(127);
        execv(argv[0], argv.data());
        _exit(127);
    }
    return pid;
}

/// Exit code of a child, or -1 when a signal ended it.
int waitExit(pid_t pid)
{
    int status = 0;
    if (waitpid(pid, &status, 0) != pid) return -2;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// Frames with status "done" in a manifest, or {} while it does not exist yet.
std::set<int> doneFrames(const std::string& manifest)
{
    std::set<int> done;
    std::error_code ec;
    if (!fs::exists(manifest, ec)) return done;
    const json m = readJson(manifest); // renamed into place whole: never a partial file
    for (const json& e : m["entries"])
        if (e["status"] == "done") done.insert(e["frame"].get<int>());
    return done;
}

} // namespace

TEST(AnimateJob, ResumesAfterASigkillWithoutRecomputingFinishedFrames)
{
    Fixture fx;
    std::string six = std::string(kAnim).replace(std::string(kAnim).find("\"frames\":3"), 10, "\"frames\":6");
    six.replace(six.find("\"frame\":2"), 9, "\"frame\":5");
    const std::string spec = fx.dir.file("anim6.json");
    writeText(spec, six);
    const int frames = 6;
    // The uninterrupted run every frame is compared with.
    ASSERT_EQ(waitExit(spawnCli(animateArgs(fx, spec, fx.dir.file("whole")), fx.dir.file("whole.log"))), 0)
        << readBytes(fx.dir.file("whole.log"));

    // The same run as a child, SIGKILLed as soon as its manifest lists a finished frame (~0.3 s a frame).
    const std::string out = fx.dir.file("out"), manifest = out + "/manifest.json";
    const std::vector<std::string> args = animateArgs(fx, spec, out);
    const pid_t pid = spawnCli(args, fx.dir.file("killed.log"));
    ASSERT_GT(pid, 0);
    const auto start = std::chrono::steady_clock::now();
    while (doneFrames(manifest).empty() && std::chrono::steady_clock::now() - start < std::chrono::seconds(300))
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    kill(pid, SIGKILL);
    ASSERT_EQ(waitExit(pid), -1) << "the run ended before it was killed:\n" << readBytes(fx.dir.file("killed.log"));
    const std::set<int> finished = doneFrames(manifest);
    ASSERT_FALSE(finished.empty());
    ASSERT_LT(int(finished.size()), frames) << "killed after the last frame";
    const json killed = readJson(manifest);
    std::map<int, fs::file_time_type> written;
    for (int f : finished) written[f] = fs::last_write_time(out + "/" + frameFile("deformed", f));

    // Rerun the same command: the finished frames are skipped, not recomputed.
    ASSERT_EQ(waitExit(spawnCli(args, fx.dir.file("again.log"))), 0) << readBytes(fx.dir.file("again.log"));
    const std::string log = readBytes(fx.dir.file("again.log"));
    EXPECT_NE(log.find(msg(frames - int(finished.size()), " done, ", finished.size(), " resumed, 0 failed")),
              std::string::npos) << log;
    const json after = readJson(manifest);
    ASSERT_EQ(after["entries"].size(), std::size_t(frames));
    for (int f : finished) {
        EXPECT_NE(log.find(msg("frame ", f, " (", f + 1, "/", frames, "): files match the manifest, skipped")),
                  std::string::npos) << log;
        // Not rewritten: same file time, and its entry (with the compute time "ms") carried over unchanged.
        EXPECT_EQ(fs::last_write_time(out + "/" + frameFile("deformed", f)), written[f]) << f;
        for (const json& e : killed["entries"])
            if (e["frame"] == f) EXPECT_EQ(after["entries"][f], e) << f;
    }
    // Every frame, resumed or computed after the kill, has the uninterrupted run's bytes.
    for (int f = 0; f < frames; ++f) {
        EXPECT_TRUE(fx.frame("out", f) == fx.frame("whole", f)) << "frame " << f;
        EXPECT_EQ(after["entries"][f]["status"], "done") << f;
    }
}

TEST(AnimateJob, MergeWithAMissingShardListsItsFramesAndFails)
{
    Fixture fx;
    ASSERT_EQ(fx.animate("out", "--shard 0/2"), 0);
    EXPECT_EQ(runCli(msg("animate --merge ", fx.dir.file("out")), fx.dir.file("merge.log")), 1);
    const json m = readJson(fx.dir.file("out/manifest.json"));
    EXPECT_EQ(m["missing"], json::parse("[1]"));
    EXPECT_EQ(m["shards"]["found"], json::parse("[0]"));
    EXPECT_NE(readBytes(fx.dir.file("merge.log")).find("missing [1]"), std::string::npos);
}

TEST(AnimateJob, BadInputExitsWithAClearMessageAndWritesNothing)
{
    Fixture fx;
    EXPECT_EQ(fx.animate("a", "--shard 2/2"), 2);
    EXPECT_NE(readBytes(fx.dir.file("a.log")).find("shard index 2 must be below the shard count 2"), std::string::npos);
    EXPECT_EQ(fx.animate("b", "--frames 2-7"), 1);
    EXPECT_NE(readBytes(fx.dir.file("b.log")).find("frames 2-7 are outside 0..2"), std::string::npos);
    writeText(fx.spec, std::string(kAnim).replace(std::string(kAnim).find("\"frame\":2"), 9, "\"frame\":5"));
    EXPECT_EQ(fx.animate("c"), 1);
    EXPECT_NE(readBytes(fx.dir.file("c.log")).find("frame 5 is outside 0..2"), std::string::npos) << readBytes(fx.dir.file("c.log"));
    writeText(fx.spec, kAnim);
    writeText(fx.dir.file("file"), "x");
    EXPECT_EQ(runCli(msg("animate ", fx.model, " --spec ", fx.spec, " -o ", fx.dir.file("file/out"), " ", kFlags), fx.dir.file("d.log")), 1);
    EXPECT_NE(readBytes(fx.dir.file("d.log")).find("cannot create output directory"), std::string::npos);
    for (const char* d : {"a", "b", "c"}) EXPECT_FALSE(fs::exists(fx.dir.file(d))) << d;
}

TEST(Batch, RunsEveryJobRecordsFailuresAndResumes)
{
    Fixture fx;
    writeText(fx.dir.file("jobs.json"), msg(R"({"jobs":[
      {"kind":"deform","input":")", fx.model, R"(","output":"bend","args":["--spec",")",
                                           std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json", R"(","--stage1-only","--nodes","48"]},
      {"kind":"to-vdb","input":"no-such.ply","output":"bad.vdb"},
      {"kind":"to-vdb","input":")", fx.model, R"(","output":"in.vdb","args":["--cells","12"]}]})"));
    const std::string run = msg("-q batch ", fx.dir.file("jobs.json"), " -o ", fx.dir.file("b"));
    // A temporary that a killed earlier run left in a job's folder is not one of its outputs.
    fs::create_directories(fx.dir.file("b/bend"));
    writeText(fx.dir.file("b/bend/.sw12345-0.tmp"), "half a file");
    EXPECT_EQ(runCli(run, fx.dir.file("1.log")), 1); // one job failed, the others went on
    const json m = readJson(fx.dir.file("b/manifest.json"));
    ASSERT_EQ(m["entries"].size(), 3u);
    EXPECT_EQ(m["entries"][0]["status"], "done");
    EXPECT_EQ(m["entries"][0]["files"].dump().find(".tmp"), std::string::npos) << m["entries"][0]["files"].dump();
    EXPECT_EQ(m["entries"][1]["status"], "failed");
    EXPECT_NE(m["entries"][1]["message"].get<std::string>().find("no-such.ply"), std::string::npos);
    EXPECT_EQ(m["entries"][2]["files"][0]["path"], "in.vdb");
    EXPECT_EQ(runCli(run, fx.dir.file("2.log")), 1);
    EXPECT_NE(readBytes(fx.dir.file("2.log")).find("0 done, 2 resumed, 1 failed"), std::string::npos) << readBytes(fx.dir.file("2.log"));
    writeText(fx.dir.file("kinds.json"), R"({"jobs":[{"kind":"render","input":"a","output":"b"}]})");
    EXPECT_EQ(runCli(msg("batch ", fx.dir.file("kinds.json"), " -o ", fx.dir.file("c")), fx.dir.file("3.log")), 1);
    EXPECT_NE(readBytes(fx.dir.file("3.log")).find("\"kind\" must be one of deform, animate, to-vdb"), std::string::npos);
}

// A render farm's 10,000-frame run joined every preview into one strip 1.6 M pixels wide (about
// 8 GB of floats, and a PNG our own readers refuse): the strip now shows as many frames as fit
// kMaxImageSide, spread evenly over the run.
TEST(AnimateJob, TheStripShowsAsManyFramesAsFitTheWidestPicture)
{
    const std::vector<std::size_t> few = stripFrames(3, 160);
    EXPECT_EQ(few, (std::vector<std::size_t>{0, 1, 2}));
    const std::vector<std::size_t> all = stripFrames(102, 160); // 102 x 160 = 16,320 pixels
    ASSERT_EQ(all.size(), 102u);
    for (std::size_t k = 0; k < all.size(); ++k) EXPECT_EQ(all[k], k);
    const std::vector<std::size_t> many = stripFrames(10000, 160);
    ASSERT_EQ(many.size(), std::size_t(kMaxImageSide / 160));
    EXPECT_EQ(many.front(), 0u);
    EXPECT_EQ(many.back(), 9999u);
    for (std::size_t k = 1; k < many.size(); ++k) {
        EXPECT_GT(many[k], many[k - 1]);
        EXPECT_LE(many[k] - many[k - 1], 100u); // evenly: 9999 / 101 = 99 frames apart
        EXPECT_GE(many[k] - many[k - 1], 98u);
    }
    EXPECT_EQ(stripFrames(5, 20000), (std::vector<std::size_t>{0})); // wider than any strip: the first frame
}
