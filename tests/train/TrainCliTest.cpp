#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/AtomicFile.h"
#include "core/Memory.h"
#include "image/TextureIO.h"
#include "train/TrainingData.h"
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

// A folder whose pictures would not fit --max-memory is refused before any picture is decoded
// (the pictures' data is garbage behind valid headers), naming the --downscale that fits; that
// downscale then passes the check (and reaches the corrupt data).
TEST(TrainCliTest, PicturesOverTheMemoryBudgetAreRefusedBeforeDecoding)
{
    test::TempDir dir;
    writeFileAtomic(dir.file("box.obj"), colouredBox());
    ASSERT_EQ(test::runCli("-q from-mesh " + dir.file("box.obj") + " -o " + dir.file("box.ply") +
                           " --views 4 --test-views 0 --size 96 --iterations 1 --init-gaussians 50 --views-dir " + dir.file("views")),
              0);
    std::vector<PictureSize> sizes;
    for (const auto& e : std::filesystem::directory_iterator(dir.file("views/images"))) {
        sizes.push_back(readTextureSize(e.path().string()));
        std::string png = test::fileBytes(e.path().string());
        for (std::size_t i = 40; i < png.size(); ++i) png[i] = char(i * 7); // past the IHDR: garbage
        writeFileAtomic(e.path().string(), png);
    }
    ASSERT_EQ(sizes.size(), 4u);
    const double atOne = pictureMemoryBytes(sizes, 1), atThree = pictureMemoryBytes(sizes, 3);
    const std::size_t budget = std::size_t((pictureMemoryBytes(sizes, 2) + atThree) / 2); // 3 fits, 2 does not
    ASSERT_GT(pictureMemoryBytes(sizes, 2), double(budget));
    ASSERT_LT(atThree, double(budget));
    const std::string log = dir.file("log.txt");
    const std::string train = "train " + dir.file("views") + " -o " + dir.file("t.ply") + " --iterations 1 --max-memory " +
                              std::to_string(budget);
    EXPECT_EQ(test::runCli(train, log), 1);
    const std::string text = test::fileBytes(log);
    EXPECT_NE(text.find(msg(dir.file("views"), ": its 4 pictures need ", formatBytes(atOne), " at --downscale 1")), std::string::npos) << text;
    EXPECT_NE(text.find("(--max-memory): --downscale 3 fits"), std::string::npos) << text;
    EXPECT_FALSE(std::filesystem::exists(dir.file("t.ply")));
    EXPECT_EQ(test::runCli(train + " --downscale 3", log), 1);
    EXPECT_NE(test::fileBytes(log).find(".png: cannot read PNG"), std::string::npos) << test::fileBytes(log);
}

// from-mesh holds every view while it trains: `--views 100000` grew past 20 GB. Views past
// --max-memory are refused before any is rendered.
TEST(TrainCliTest, FromMeshViewsOverTheMemoryBudgetAreRefusedBeforeRendering)
{
    test::TempDir dir;
    writeFileAtomic(dir.file("box.obj"), colouredBox());
    const std::string log = dir.file("log.txt");
    const std::string run = "from-mesh " + dir.file("box.obj") + " -o " + dir.file("out/box.ply") +
                            " --size 64 --iterations 1 --init-gaussians 50 --test-views 2 --max-memory 1M --views ";
    // (30 + 2) views of 64x64 at 16 B a pixel: 2 MiB.
    EXPECT_EQ(test::runCli(run + "30", log), 1);
    const std::string text = test::fileBytes(log);
    EXPECT_NE(text.find("box.obj: 30 + 2 views of 64x64 need 2 MiB, over --max-memory 1 MiB"), std::string::npos) << text;
    EXPECT_EQ(text.find("rendered"), std::string::npos) << text;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out")));
    EXPECT_EQ(test::runCli(run + "10", log), 0) << test::fileBytes(log); // 12 views: 0.75 MiB
    EXPECT_TRUE(std::filesystem::exists(dir.file("out/box.ply")));
    EXPECT_EQ(test::runCli("from-mesh " + dir.file("box.obj") + " -o " + dir.file("x.ply") + " --test-views 100001", log), 2);
}

// --random-points 3e8 filled the machine before the first step: a start larger than the cap that
// densification keeps is a usage error, in train and in from-mesh.
TEST(TrainCliTest, AStartLargerThanMaxGaussiansIsAUsageError)
{
    test::TempDir dir;
    writeFileAtomic(dir.file("box.obj"), colouredBox());
    const std::string log = dir.file("log.txt");
    const std::string mesh = "from-mesh " + dir.file("box.obj") + " -o " + dir.file("box.ply") +
                             " --views 4 --test-views 0 --size 32 --iterations 1 --max-gaussians 1000 --init-gaussians ";
    EXPECT_EQ(test::runCli(mesh + "1001", log), 2);
    EXPECT_NE(test::fileBytes(log).find("--init-gaussians 1001 is more than --max-gaussians 1000"), std::string::npos)
        << test::fileBytes(log);
    ASSERT_EQ(test::runCli("-q " + mesh + "1000 --views-dir " + dir.file("views"), log), 0) << test::fileBytes(log);
    const std::string train = "train " + dir.file("views") + " -o " + dir.file("t.ply") + " --iterations 1 --max-gaussians 1000 --random-points ";
    EXPECT_EQ(test::runCli(train + "1001", log), 2);
    EXPECT_NE(test::fileBytes(log).find("--random-points 1001 is more than --max-gaussians 1000"), std::string::npos)
        << test::fileBytes(log);
    EXPECT_FALSE(std::filesystem::exists(dir.file("t.ply")));
    EXPECT_EQ(test::runCli("-q " + train + "1000", log), 0) << test::fileBytes(log);
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

// No output of from-mesh, train or eval --mesh may replace a file they read: the .mtl and texture
// an OBJ names, a training picture; --views-dir is checked before the work, its folders too.
TEST(TrainCliTest, NoOutputReplacesAFileTheCommandRead)
{
    test::TempDir dir;
    writeFileAtomic(dir.file("box.obj"), "mtllib box.mtl\n" + colouredBox());
    writeFileAtomic(dir.file("box.mtl"), "newmtl m\nKd 0.5 0.5 0.5\n");
    const std::string fast = " --views 2 --test-views 0 --size 16 --iterations 5 --sh-degree 0 --init-gaussians 100";
    const std::string log = dir.file("log.txt");
    EXPECT_EQ(test::runCli("-q from-mesh " + dir.file("box.obj") + " -o " + dir.file("box.mtl") + fast, log), 1);
    EXPECT_NE(test::fileBytes(log).find("is also an input"), std::string::npos) << test::fileBytes(log);
    EXPECT_EQ(test::fileBytes(dir.file("box.mtl")), "newmtl m\nKd 0.5 0.5 0.5\n");
    ASSERT_EQ(test::runCli("-q from-mesh " + dir.file("box.obj") + " -o " + dir.file("m.ply") + fast + " --views-dir " + dir.file("v"), log), 0)
        << test::fileBytes(log);
    const std::string picture = test::fileBytes(dir.file("v/images/view_0.png"));
    EXPECT_EQ(test::runCli("-q train " + dir.file("v") + " -o " + dir.file("v/images/view_0.png") + " --iterations 3 --random-points 50", log), 1);
    EXPECT_NE(test::fileBytes(log).find("is also an input"), std::string::npos) << test::fileBytes(log);
    EXPECT_EQ(test::fileBytes(dir.file("v/images/view_0.png")), picture);
    // --views-dir: a planted images/ link, or the model's own path, refused before any training.
    std::filesystem::create_directories(dir.file("w"));
    std::filesystem::create_directories(dir.file("elsewhere"));
    std::filesystem::create_directory_symlink(dir.file("elsewhere"), dir.file("w/images"));
    EXPECT_EQ(test::runCli("-q from-mesh " + dir.file("box.obj") + " -o " + dir.file("n.ply") + fast + " --views-dir " + dir.file("w"), log), 1);
    EXPECT_NE(test::fileBytes(log).find("w/images: is a symbolic link"), std::string::npos) << test::fileBytes(log);
    EXPECT_TRUE(std::filesystem::is_empty(dir.file("elsewhere")));
    EXPECT_EQ(test::runCli("-q from-mesh " + dir.file("box.obj") + " -o " + dir.file("p.ply") + fast + " --views-dir " + dir.file("p.ply"), log), 1);
    EXPECT_NE(test::fileBytes(log).find("is where --views-dir"), std::string::npos) << test::fileBytes(log);
    EXPECT_FALSE(std::filesystem::exists(dir.file("n.ply")));
    // eval --mesh writes its montage as PNG: another name is a usage error, not PNG bytes under it.
    EXPECT_EQ(test::runCli("-q eval --rest " + dir.file("m.ply") + " --deformed " + dir.file("m.ply") + " --spec " +
                               SPLATWARP_SOURCE_DIR + "/samples/specs/rigid.json --mesh " + dir.file("box.obj") +
                               " --views 2 --size 16 --montage " + dir.file("m.exr"), log), 2);
    EXPECT_NE(test::fileBytes(log).find("the montage is a PNG"), std::string::npos) << test::fileBytes(log);
}

// A mesh far beyond float's usable range, or far too small, trained to Gaussians every reader
// refuses (exit 0): refused when it is read, before the training. (The writers refuse such models
// too: Reliability.ValuesThatOverflowInUseAreRefusedOrDropped.)
TEST(TrainCliTest, AMeshWhoseSplatsReadersWouldRefuseIsRefusedFirst)
{
    test::TempDir dir;
    std::string far;
    for (int i = 0; i < 8; ++i) far += msg("v ", (i & 1) ? 2e20 : 1e20, " ", (i & 2) ? 2e20 : 1e20, " ", (i & 4) ? 2e20 : 1e20, "\n");
    writeFileAtomic(dir.file("far.obj"), far + "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n");
    const std::string log = dir.file("log.txt");
    EXPECT_EQ(test::runCli("from-mesh " + dir.file("far.obj") + " -o " + dir.file("far.ply") +
                               " --views 2 --test-views 0 --size 16 --iterations 3 --sh-degree 0 --init-gaussians 50", log), 1);
    EXPECT_NE(test::fileBytes(log).find("beyond 1e14"), std::string::npos) << test::fileBytes(log);
    EXPECT_EQ(test::fileBytes(log).find("train:"), std::string::npos) << "it trained first";
    EXPECT_FALSE(std::filesystem::exists(dir.file("far.ply")));
    writeFileAtomic(dir.file("tiny.obj"), "v 0 0 0\nv 1e-30 0 0\nv 0 1e-30 0\nf 1 2 3\n");
    EXPECT_EQ(test::runCli("from-mesh " + dir.file("tiny.obj") + " -o " + dir.file("tiny.ply") +
                               " --views 2 --test-views 0 --size 16 --iterations 3 --sh-degree 0 --init-gaussians 50", log), 1);
    EXPECT_NE(test::fileBytes(log).find("below 1e-12"), std::string::npos) << test::fileBytes(log);
}

} // namespace
} // namespace splatwarp
