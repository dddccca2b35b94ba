#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/TestSupport.h"

using namespace splatwarp::test;

namespace {
const std::string kSpecs = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/";
}

TEST(DeformCli, StageOneWritesBaselineAndReport)
{
    TempDir dir;
    ASSERT_EQ(runCli("sample stripes --count 3000 -o " + dir.file("in.ply")), 0);
    const std::string out = dir.file("out");
    ASSERT_EQ(runCli("deform " + dir.file("in.ply") + " --spec " + kSpecs + "bend.json -o " + out +
                         " --stage1-only --nodes 64 --k 8 --seed 1",
                     dir.file("log.txt")),
              0);
    EXPECT_TRUE(std::filesystem::exists(out + "/baseline.ply"));
    std::ifstream in(out + "/report.json");
    const nlohmann::json r = nlohmann::json::parse(in);
    EXPECT_EQ(r["input"]["gaussians"], 3000);
    EXPECT_EQ(r["graph"]["nodes"], 64);
    EXPECT_EQ(r["graph"]["seed"], 1);
    EXPECT_GT(r["solver"]["iterations"].get<int>(), 0);
    EXPECT_LT(r["solver"]["final"]["total"].get<double>(), r["solver"]["initial"]["total"].get<double>());
    EXPECT_GT(r["stage1"]["moving"].get<int>(), 0);
    for (const char* k : {"read", "graph", "solve", "weights", "update", "write"}) EXPECT_TRUE(r["timingsMs"].contains(k)) << k;
    // The baseline reads back with the same count.
    EXPECT_EQ(runCli("info " + out + "/baseline.ply"), 0);
}

TEST(DeformCli, ErrorsAndExitCodes)
{
    TempDir dir;
    ASSERT_EQ(runCli("sample stripes --count 500 -o " + dir.file("in.ply")), 0);
    // Without --stage1-only: Stage II is not there yet -> exit 1 with a clear message.
    const std::string log = dir.file("log.txt");
    EXPECT_EQ(runCli("deform " + dir.file("in.ply") + " --spec " + kSpecs + "bend.json -o " + dir.file("o"), log), 1);
    std::ifstream l(log);
    const std::string text((std::istreambuf_iterator<char>(l)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("Stage II is not available yet"), std::string::npos) << text;
    // A bad spec -> exit 1, nothing written.
    std::ofstream(dir.file("bad.json")) << R"({"version":1,"handles":[{"nodes":[0],"bogus":1}]})";
    EXPECT_EQ(runCli("deform " + dir.file("in.ply") + " --spec " + dir.file("bad.json") + " -o " + dir.file("o2") +
                     " --stage1-only"),
              1);
    EXPECT_FALSE(std::filesystem::exists(dir.file("o2") + "/baseline.ply"));
    // Missing required option -> usage error 2.
    EXPECT_EQ(runCli("deform " + dir.file("in.ply") + " --stage1-only"), 2);
}
