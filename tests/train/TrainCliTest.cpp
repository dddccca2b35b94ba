#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/AtomicFile.h"
#include "io/GaussianIO.h"
#include "mesh/BadMeshes.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

/// A two-coloured cube-ish box as an OBJ with vertex colours (v x y z r g b).
std::string colouredBox()
{
    std::string s;
    for (int i = 0; i < 8; ++i)
        s += msg("v ", (i & 1) ? 0.5 : -0.5, " ", (i & 2) ? 0.3 : -0.3, " ", (i & 4) ? 0.4 : -0.4, " ", (i & 1) ? 0.9 : 0.2,
                 " 0.4 ", (i & 4) ? 0.8 : 0.1, "\n");
    return s + "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n";
}

// from-mesh writes the model, the views (graphdeco layout) and a report; train reads those views.
TEST(TrainCliTest, FromMeshThenTrainOnItsViews)
{
    test::TempDir dir;
    writeFileAtomic(dir.file("box.obj"), colouredBox());
    const std::string log = dir.file("log.txt");
    ASSERT_EQ(test::runCli("from-mesh " + dir.file("box.obj") + " -o " + dir.file("box.ply") +
                               " --views 6 --test-views 2 --size 24 --iterations 40 --sh-degree 0 --init-gaussians 300"
                               " --views-dir " + dir.file("views") + " --report " + dir.file("r.json"),
                           log),
              0)
        << test::fileBytes(log);
    EXPECT_GT(readGaussians(dir.file("box.ply")).size(), 100u);
    EXPECT_TRUE(std::filesystem::exists(dir.file("views/cameras.json")));
    EXPECT_TRUE(std::filesystem::exists(dir.file("views/images/view_0.png")));
    EXPECT_TRUE(std::filesystem::exists(dir.file("views/test/images/test_view_1.png")));
    const nlohmann::json r = nlohmann::json::parse(test::fileBytes(dir.file("r.json")));
    EXPECT_EQ(r["trainViews"], 6);
    EXPECT_EQ(r["test"]["views"].size(), 2u);
    EXPECT_GT(r["test"]["psnr"].get<double>(), 10.0);
    EXPECT_NE(test::fileBytes(log).find("held-out PSNR"), std::string::npos);

    ASSERT_EQ(test::runCli("-q train " + dir.file("views") + " -o " + dir.file("t.ply") + " --iterations 10 --random-points 200 "
                               "--holdout 3 --report " + dir.file("t.json"),
                           log),
              0)
        << test::fileBytes(log);
    const nlohmann::json t = nlohmann::json::parse(test::fileBytes(dir.file("t.json")));
    EXPECT_EQ(t["format"], "graphdeco");
    EXPECT_EQ(t["testViews"], 2); // views 0 and 3 of 6
}

TEST(TrainCliTest, BadMeshesExitOneNamingTheFile)
{
    test::TempDir dir;
    for (const auto& [name, named] : test::writeBadMeshes(dir)) {
        const std::string log = dir.file("log.txt");
        EXPECT_EQ(test::runCli("from-mesh " + dir.file(name) + " -o " + dir.file("x.ply"), log), 1) << name;
        EXPECT_NE(test::fileBytes(log).find(named), std::string::npos) << test::fileBytes(log);
        EXPECT_FALSE(std::filesystem::exists(dir.file("x.ply")));
    }
    EXPECT_EQ(test::runCli("train " + dir.path().string() + " -o " + dir.file("x.ply")), 1); // no cameras
}

} // namespace
} // namespace splatwarp
