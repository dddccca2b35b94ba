// The editor's server (edit/EditServer.h) on 127.0.0.1, port 0, hit with httplib's client: the
// token, the Host check, bounded and malformed bodies, bad specs, save names, pose bytes, refine
// with progress and cancel, two clients at once; and `splatwarp edit` itself, whose saved spec
// `splatwarp deform` replays byte for byte.
#include <gtest/gtest.h>

#include <httplib.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <csignal>
#include <filesystem>
#include <spawn.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

#include "deform/AnimSpec.h"
#include "demo/DemoModels.h"
#include "edit/DragSpec.h"
#include "edit/EditRequest.h"
#include "edit/EditServer.h"
#include "edit/GaussianLayout.h"
#include "io/GaussianIO.h"
#include "job/DeformSession.h"
#include "support/TestSupport.h"

extern char** environ;

using namespace splatwarp;
using namespace splatwarp::test;
namespace fs = std::filesystem;

namespace {

using edit::bendDragSpec;

struct Fixture {
    TempDir dir;
    edit::EditServerOptions options;
    std::unique_ptr<edit::EditServer> server;
    std::unique_ptr<httplib::Client> client;

    explicit Fixture(bool stage1Only = true, int iterations = 6)
    {
        DemoModelOptions so;
        so.count = 2000;
        writePly(dir.file("in.ply"), makeDemoModel("stripes", so));
        options.job.input = dir.file("in.ply");
        options.job.outDir = dir.file("out");
        options.job.nodes = 64;
        options.job.grid.cells = 16;
        options.job.stage2.iterations = iterations;
        options.job.heldOut.points = 5000;
        options.job.stage1Only = stage1Only;
        options.token = "test-token-0123456789";
    }
    void start()
    {
        server = std::make_unique<edit::EditServer>(options);
        server->start();
        client = connect();
    }
    std::unique_ptr<httplib::Client> connect(bool withToken = true) const
    {
        auto c = std::make_unique<httplib::Client>("127.0.0.1", server->port());
        if (withToken) c->set_default_headers({{"Authorization", "Bearer " + options.token}});
        c->set_read_timeout(120, 0);
        return c;
    }
    httplib::Result post(const std::string& path, const std::string& body) const
    {
        return client->Post(path.c_str(), body, "application/json");
    }
    nlohmann::json progress() const { return nlohmann::json::parse(client->Get("/api/progress")->body); }
    /// Polls GET /api/progress until `until` holds (or 120 s pass).
    nlohmann::json waitFor(const std::function<bool(const nlohmann::json&)>& until) const
    {
        for (int i = 0; i < 12000; ++i) {
            const nlohmann::json p = progress();
            if (until(p)) return p;
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        return progress();
    }
};

int status(const httplib::Result& r) { return r ? r->status : -1; }

} // namespace

TEST(EditServer, RequestChecks)
{
    using namespace splatwarp::edit;
    EXPECT_TRUE(hostAllowed("127.0.0.1:8080", "127.0.0.1", 8080));
    EXPECT_TRUE(hostAllowed("localhost:8080", "127.0.0.1", 8080));
    EXPECT_TRUE(hostAllowed("LOCALHOST", "127.0.0.1", 8080));
    EXPECT_TRUE(hostAllowed("[::1]:8080", "127.0.0.1", 8080));
    EXPECT_FALSE(hostAllowed("127.0.0.1:8081", "127.0.0.1", 8080));
    EXPECT_FALSE(hostAllowed("evil.example:8080", "127.0.0.1", 8080));
    EXPECT_FALSE(hostAllowed("", "127.0.0.1", 8080));
    EXPECT_FALSE(hostAllowed("192.168.1.5:8080", "127.0.0.1", 8080));
    EXPECT_TRUE(hostAllowed("192.168.1.5:8080", "0.0.0.0", 8080)); // a wildcard bind: IP literals only
    EXPECT_FALSE(hostAllowed("evil.example:8080", "0.0.0.0", 8080));
    EXPECT_TRUE(tokenMatches("abc", "abc"));
    EXPECT_FALSE(tokenMatches("abd", "abc"));
    EXPECT_FALSE(tokenMatches("", ""));
    EXPECT_EQ(randomToken().size(), 32u);
    EXPECT_NE(randomToken(), randomToken());
    EXPECT_TRUE(tokenWellFormed("test-token-0123456789"));
    EXPECT_FALSE(tokenWellFormed("short"));
    EXPECT_FALSE(tokenWellFormed("has space in it 0123456789"));
    EXPECT_EQ(saveNameProblem("bend-1.v2"), "");
    for (const char* bad : {"", "..", "../x", "a/b", ".hidden", "a\\b", "x y", "/abs"}) EXPECT_NE(saveNameProblem(bad), "") << bad;
    EXPECT_EQ(shellQuoted("runs/a-1.ply"), "runs/a-1.ply");
    EXPECT_EQ(shellQuoted("my model;x.ply"), "'my model;x.ply'");
    EXPECT_EQ(shellQuoted("it's"), "'it'\\''s'");
    EXPECT_EQ(shellQuoted(""), "''");
    EXPECT_FALSE(tooManyRanges("bytes=0-99"));
    EXPECT_TRUE(tooManyRanges("bytes=0-,0-"));
}

TEST(EditServer, TokenMissingOrWrongIs403)
{
    Fixture fx;
    fx.start();
    auto anonymous = fx.connect(false);
    EXPECT_EQ(status(anonymous->Get("/api/model")), 403);
    EXPECT_EQ(status(anonymous->Get("/api/model?token=wrong-token-0123456789")), 403);
    EXPECT_EQ(status(anonymous->Post("/api/pose", bendDragSpec(10), "application/json")), 403);
    EXPECT_EQ(status(anonymous->Get("/")), 403);
    const httplib::Result ok = anonymous->Get(("/api/model?token=" + fx.options.token).c_str());
    ASSERT_EQ(status(ok), 200);
    EXPECT_EQ(ok->get_header_value("Access-Control-Allow-Origin"), ""); // no CORS
    EXPECT_EQ(status(fx.client->Get("/api/model")), 200); // Authorization: Bearer
    const GaussianCloud model = edit::decodeGaussians(ok->body);
    EXPECT_EQ(model.size(), 2000u);
}

TEST(EditServer, ForeignHostIs403)
{
    Fixture fx;
    fx.start();
    EXPECT_EQ(status(fx.client->Get("/api/graph", {{"Host", "evil.example:" + std::to_string(fx.server->port())}})), 403);
    EXPECT_EQ(status(fx.client->Get("/api/graph", {{"Host", "127.0.0.1:1"}})), 403);
    EXPECT_EQ(status(fx.client->Get("/api/graph", {{"Host", "localhost:" + std::to_string(fx.server->port())}})), 200);
}

TEST(EditServer, OversizedMalformedAndBadSpecsAreRefused)
{
    Fixture fx;
    fx.start();
    EXPECT_EQ(status(fx.post("/api/pose", std::string(2 << 20, ' '))), 413);
    const httplib::Result malformed = fx.post("/api/pose", "{\"version\": 1, ");
    ASSERT_EQ(status(malformed), 400);
    EXPECT_NE(malformed->body.find("invalid JSON"), std::string::npos) << malformed->body;
    const httplib::Result unknown = fx.post("/api/pose", R"({"version": 1, "handles": [], "colour": 3})");
    ASSERT_EQ(status(unknown), 400);
    EXPECT_NE(unknown->body.find("colour"), std::string::npos) << unknown->body;
    const httplib::Result empty = fx.post("/api/pose", R"({"version": 1, "units": "bbox", "handles": [
        {"box": {"min": [2, 2, 2], "max": [3, 3, 3]}, "fixed": true}]})");
    EXPECT_EQ(status(empty), 400) << (empty ? empty->body : "");
    EXPECT_EQ(status(fx.post("/api/save", "not json")), 400);
    EXPECT_EQ(status(fx.post("/api/save", R"({"name": "early"})")), 400); // no pose yet
    EXPECT_EQ(status(fx.post("/api/refine", "")), 400);                     // Stage I only
    EXPECT_EQ(status(fx.client->Get("/api/nothing")), 404);
    // Bytes that are not UTF-8, quoted back in the message: 400 with a readable reply, not 500.
    const httplib::Result notUtf8 = fx.post("/api/save", "{\"name\": \"\xff\"}");
    EXPECT_EQ(status(notUtf8), 400) << (notUtf8 ? notUtf8->body : "");
    EXPECT_EQ(status(fx.post("/api/save", "\xff")), 400);
    // A spec posted as a form (curl -d's default) meets httplib's 8 KiB: the reply says what to send.
    std::string big = bendDragSpec(30);
    big.insert(big.size() - 1, std::string(20000, ' '));
    const httplib::Result form = fx.client->Post("/api/pose", big, "application/x-www-form-urlencoded");
    ASSERT_EQ(status(form), 413);
    EXPECT_NE(form->body.find("Content-Type: application/json"), std::string::npos) << form->body;
    EXPECT_EQ(status(fx.post("/api/pose", big)), 200);
    // Many ranges of one file would each be a copy of it in the reply.
    EXPECT_EQ(status(fx.client->Get("/api/graph", {{"Range", "bytes=0-,0-,0-"}})), 416);
    EXPECT_EQ(status(fx.post("/api/pose", bendDragSpec(30))), 200); // the server still serves
}

TEST(EditServer, SaveNamesStayInsideTheOutputFolder)
{
    Fixture fx;
    fx.start();
    ASSERT_EQ(status(fx.post("/api/pose", bendDragSpec(45))), 200);
    fs::create_directories(fx.dir.file("outside"));
    fs::create_directory_symlink(fx.dir.file("outside"), fx.dir.file("out/link"));
    for (const char* name : {"../x", "a/b", ".hidden", "..", "", "link", "/tmp/abs"}) {
        const httplib::Result r = fx.post("/api/save", nlohmann::json{{"name", name}}.dump());
        EXPECT_EQ(status(r), 400) << name << ": " << (r ? r->body : "");
    }
    EXPECT_EQ(status(fx.post("/api/save", R"({"name": 3})")), 400);
    EXPECT_EQ(status(fx.post("/api/save", R"({"name": "ok", "path": "/tmp"})")), 400);
    EXPECT_TRUE(fs::is_empty(fx.dir.file("outside")));
    EXPECT_FALSE(fs::exists(fx.dir.file("x")));
    const httplib::Result ok = fx.post("/api/save", R"({"name": "ok"})");
    ASSERT_EQ(status(ok), 200) << (ok ? ok->body : "");
    EXPECT_TRUE(fs::exists(fx.dir.file("out/ok/spec.json")));
    EXPECT_TRUE(fs::exists(fx.dir.file("out/ok/baseline.ply")));
    EXPECT_TRUE(fs::exists(fx.dir.file("out/ok/report.json")));
    std::vector<std::string> top;
    for (const auto& e : fs::directory_iterator(fx.dir.path())) top.push_back(e.path().filename().string());
    std::sort(top.begin(), top.end());
    EXPECT_EQ(top, (std::vector<std::string>{"in.ply", "out", "outside"}));
}

TEST(EditServer, PoseRepliesWithTheBytesOfTheSessionsPreview)
{
    Fixture fx;
    fx.start();
    DeformSession session(fx.options.job, DeformSpec{});
    for (double degrees : {20.0, 90.0}) { // the second one warm-starts from the first, in both
        const httplib::Result r = fx.post("/api/pose", bendDragSpec(degrees));
        ASSERT_EQ(status(r), 200);
        const DeformSession::Preview expected = session.preview(parseDeformSpec(bendDragSpec(degrees), "test"));
        EXPECT_TRUE(r->body == edit::encodePose(expected.cloud, session.rest().model.shDegree)) << degrees;
        EXPECT_EQ(r->get_header_value("X-Splatwarp-Moving"), std::to_string(expected.moving));
        EXPECT_FALSE(r->get_header_value("X-Splatwarp-Solve-Ms").empty());
        EXPECT_EQ(r->get_header_value("Content-Type"), "application/octet-stream");
        // A pose carries the geometry only; opacities and colours are the rest model's.
        EXPECT_EQ(r->body.size(), edit::kLayoutHeaderBytes + expected.cloud.size() * edit::kPoseFloats * 4);
        EXPECT_THROW(edit::decodeGaussians(r->body), InputError);
        const GaussianCloud decoded = edit::decodeGaussians(r->body, &session.rest().model);
        EXPECT_TRUE(decoded.means == expected.cloud.means);
        EXPECT_TRUE(decoded.rotations == expected.cloud.rotations);
        EXPECT_TRUE(decoded.opacities == session.rest().model.opacities);
    }
}

TEST(EditServer, RefineReportsProgressAndCancelStopsIt)
{
    Fixture fx(false, 2000);
    fx.options.job.stage2.stallTolerance = 0; // no early stop: the cancel must stop it
    fx.start();
    EXPECT_EQ(status(fx.post("/api/refine", "")), 400); // no pose
    ASSERT_EQ(status(fx.post("/api/pose", bendDragSpec(90))), 200);
    ASSERT_EQ(status(fx.post("/api/refine", "")), 202);
    EXPECT_EQ(status(fx.post("/api/refine", "")), 409);
    EXPECT_EQ(status(fx.post("/api/pose", bendDragSpec(10))), 409);
    EXPECT_EQ(status(fx.post("/api/save", R"({"name": "during"})")), 409);
    const std::string anim = fileBytes(std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend-24.json");
    EXPECT_EQ(status(fx.post("/api/save-animation?name=during", anim)), 409); // at once, not after the refine
    const nlohmann::json running = fx.waitFor(
        [](const nlohmann::json& p) { return (p["phase"] == "Stage II" && p["done"].get<int>() > 0) || p["state"] != "running"; });
    EXPECT_EQ(running["state"], "running");
    EXPECT_EQ(running["phase"], "Stage II");
    EXPECT_GT(running["total"].get<int>(), 0);
    EXPECT_TRUE(running.contains("firstProgressMs"));
    ASSERT_EQ(status(fx.post("/api/cancel", "")), 200);
    const nlohmann::json after = fx.waitFor([](const nlohmann::json& p) { return p["state"] != "running"; });
    EXPECT_EQ(after["state"], "cancelled");
    EXPECT_LT(after["done"].get<int>(), 2000);
    EXPECT_EQ(status(fx.client->Get("/api/refined")), 404);
    EXPECT_EQ(status(fx.post("/api/pose", bendDragSpec(10))), 200); // posing works again
}

TEST(EditServer, AnimationFramesAndSaves)
{
    Fixture fx;
    fx.start();
    const std::string anim = fileBytes(std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend-24.json");
    DeformSession session(fx.options.job, DeformSpec{});
    const AnimSpec parsed = parseAnimSpec(anim, "bend-24");
    const httplib::Result r = fx.post("/api/pose?frame=12", anim);
    ASSERT_EQ(status(r), 200) << (r ? r->body : "");
    EXPECT_TRUE(r->body == edit::encodePose(session.preview(frameSpec(parsed, 12)).cloud, session.rest().model.shDegree));
    EXPECT_EQ(status(fx.post("/api/pose?frame=24", anim)), 400);
    EXPECT_EQ(status(fx.post("/api/pose?frame=x", anim)), 400);
    EXPECT_EQ(status(fx.post("/api/save-animation?name=../up", anim)), 400);
    EXPECT_EQ(status(fx.post("/api/save-animation?name=bad", R"({"version": 1, "handles": []})")), 400); // no frames
    const httplib::Result saved = fx.post("/api/save-animation?name=bend24", anim);
    ASSERT_EQ(status(saved), 200) << (saved ? saved->body : "");
    const AnimSpec back = parseAnimSpec(fileBytes(fx.dir.file("out/bend24/animation.json")), "saved");
    EXPECT_EQ(back.frames, 24);
    EXPECT_EQ(frameSpecJson(back, 12)["handles"], frameSpecJson(parsed, 12)["handles"]);
    EXPECT_EQ(frameSpecJson(back, 0)["graph"]["nodes"], 64); // the session's graph, written out
    // Another graph would replay on other nodes than the ones previewed: refused, as a pose is.
    nlohmann::json other = nlohmann::json::parse(anim);
    other["graph"]["seed"] = 7; // (--nodes 64 is the fixture's, so the nodes would be overridden)
    const httplib::Result graph = fx.post("/api/save-animation?name=g2", other.dump());
    EXPECT_EQ(status(graph), 400) << (graph ? graph->body : "");
    EXPECT_FALSE(fs::exists(fx.dir.file("out/g2")));
}

TEST(EditServer, TwoClientsAtOnce)
{
    Fixture fx;
    fx.start();
    DeformSession session(fx.options.job, DeformSpec{});
    const GaussianCloud expect30 = session.pose(parseDeformSpec(bendDragSpec(30), "t")).deformed;
    const GaussianCloud expect60 = session.pose(parseDeformSpec(bendDragSpec(60), "t")).deformed;
    Vec3f lo, hi;
    centreBounds(session.rest().model, lo, hi);
    const double tolerance = 2e-3 * std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    // Each reply is its own pose (a preview warm-started from whichever pose came last: within the
    // solver's tolerance of the exact Stage I, and nowhere near the other client's).
    const auto close = [&](const std::string& body, const GaussianCloud& expected) {
        const GaussianCloud got = edit::decodeGaussians(body, &session.rest().model);
        if (got.size() != expected.size()) return false;
        for (std::size_t i = 0; i < got.means.size(); ++i)
            if (std::fabs(got.means[i] - expected.means[i]) > tolerance) return false;
        return true;
    };
    std::atomic<int> good{0};
    const auto drag = [&](double degrees, const GaussianCloud& expected) {
        auto c = fx.connect();
        for (int i = 0; i < 6; ++i) {
            const httplib::Result r = c->Post("/api/pose", bendDragSpec(degrees), "application/json");
            if (status(r) == 200 && close(r->body, expected)) ++good;
            if (status(c->Get("/api/progress")) == 200) ++good;
        }
    };
    ASSERT_FALSE(close(edit::encodePose(expect30, 0), expect60)); // the check tells the two poses apart
    std::thread a(drag, 30.0, std::cref(expect30)), b(drag, 60.0, std::cref(expect60));
    a.join();
    b.join();
    EXPECT_EQ(good.load(), 24);
}

namespace {

/// `splatwarp edit` as a child process; its first stdout line is the URL.
struct EditProcess {
    pid_t pid = -1;
    std::string url;
    int port = 0;
    std::string token;

    explicit EditProcess(const std::vector<std::string>& args)
    {
        int out[2];
        if (pipe(out) != 0) return;
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_adddup2(&actions, out[1], 1);
        posix_spawn_file_actions_addclose(&actions, out[0]);
        std::vector<std::string> all = {SPLATWARP_CLI, "-q", "edit"};
        all.insert(all.end(), args.begin(), args.end());
        std::vector<char*> argv;
        for (std::string& a : all) argv.push_back(a.data());
        argv.push_back(nullptr);
        posix_spawn(&pid, SPLATWARP_CLI, &actions, nullptr, argv.data(), environ);
        posix_spawn_file_actions_destroy(&actions);
        close(out[1]);
        char c;
        while (read(out[0], &c, 1) == 1 && c != '\n') url += c;
        close(out[0]);
        const std::size_t colon = url.rfind(':'), slash = url.find('/', colon);
        if (colon != std::string::npos && slash != std::string::npos) port = std::atoi(url.substr(colon + 1, slash - colon - 1).c_str());
        token = url.substr(url.find("token=") + 6);
    }
    /// SIGINT, then the exit code (-1 when it did not exit normally).
    int stop()
    {
        if (pid <= 0) return -1;
        kill(pid, SIGINT);
        int status = 0;
        waitpid(pid, &status, 0);
        pid = -1;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    ~EditProcess() { stop(); }
};

} // namespace

TEST(EditServer, SavedSpecReplaysWithDeformByteForByte)
{
    TempDir dir;
    ASSERT_EQ(runCli("-q sample stripes --count 2000 -o " + dir.file("in.ply")), 0);
    const std::vector<std::string> flags = {"--nodes", "64", "--cells", "16", "--iterations", "6", "--eval-points", "5000"};
    std::vector<std::string> args = {dir.file("in.ply"), "-o", dir.file("edits"), "--no-open"};
    args.insert(args.end(), flags.begin(), flags.end());
    EditProcess edit(args);
    ASSERT_GT(edit.port, 0) << edit.url;
    ASSERT_EQ(edit.url.rfind("http://127.0.0.1:", 0), 0u) << edit.url;
    httplib::Client client("127.0.0.1", edit.port);
    client.set_default_headers({{"Authorization", "Bearer " + edit.token}});
    client.set_read_timeout(120, 0);
    ASSERT_EQ(status(client.Post("/api/pose", bendDragSpec(15), "application/json")), 200);
    ASSERT_EQ(status(client.Post("/api/pose", bendDragSpec(75), "application/json")), 200);
    ASSERT_EQ(status(client.Post("/api/refine", "", "application/json")), 202);
    nlohmann::json p;
    for (int i = 0; i < 6000; ++i) {
        p = nlohmann::json::parse(client.Get("/api/progress")->body);
        if (p["state"] != "running") break;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ASSERT_EQ(p["state"], "done") << p.dump();
    EXPECT_EQ(status(client.Get("/api/refined")), 200);
    const httplib::Result saved = client.Post("/api/save", R"({"name": "bend75"})", "application/json");
    ASSERT_EQ(status(saved), 200) << (saved ? saved->body : "");
    EXPECT_NE(nlohmann::json::parse(saved->body)["replay"].get<std::string>().find("--nodes 64"), std::string::npos) << saved->body;
    EXPECT_EQ(edit.stop(), 0);
    std::string replay = "-q deform " + dir.file("in.ply") + " --spec " + dir.file("edits/bend75/spec.json") + " -o " + dir.file("cli");
    for (const std::string& f : flags) replay += " " + f;
    ASSERT_EQ(runCli(replay, dir.file("cli.log")), 0) << fileBytes(dir.file("cli.log"));
    for (const char* f : {"baseline.ply", "deformed.ply"}) {
        const std::string a = fileBytes(dir.file(std::string("edits/bend75/") + f)), b = fileBytes(dir.file(std::string("cli/") + f));
        EXPECT_FALSE(a.empty()) << f;
        EXPECT_TRUE(a == b) << f;
    }
}
