#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/AtomicFile.h"
#include "image/ImageIO.h"
#include "io/GaussianIO.h"
#include "demo/DemoModels.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

std::string slurp(const std::string& path)
{
    std::ifstream in(path);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

class RenderCliTest : public ::testing::Test {
protected:
    void SetUp() override
    {
        DemoModelOptions o;
        o.count = 2000;
        writePly(mDir.file("bar.ply"), makeDemoModel("stripes", o));
    }
    std::string model() const { return mDir.file("bar.ply"); }
    test::TempDir mDir;
};

TEST_F(RenderCliTest, SingleImageOrbitDirectoryAndExr)
{
    const std::string png = mDir.file("one.png");
    ASSERT_EQ(test::runCli("-q render " + model() + " -o " + png + " --size 48x32 --background 0.2,0.2,0.2"), 0);
    const Image img = readPng(png);
    EXPECT_EQ(img.width, 48);
    EXPECT_EQ(img.height, 32);
    EXPECT_NEAR(img.at(0, 0, 0), 0.2, 0.01); // a corner shows the background

    ASSERT_EQ(test::runCli("-q render " + model() + " --orbit 3 -o " + mDir.file("orbit") + " --size 24x24 --up z --fov 50"), 0);
    for (const char* name : {"view_000.png", "view_001.png", "view_002.png"})
        EXPECT_TRUE(std::filesystem::exists(mDir.file(std::string("orbit/") + name))) << name;

    ASSERT_EQ(test::runCli("-q render " + model() + " -o " + mDir.file("one.exr") + " --size 20x20"), 0);
    EXPECT_EQ(readExr(mDir.file("one.exr")).channels, 4);
}

TEST_F(RenderCliTest, CameraFileAndErrors)
{
    const std::string cams = mDir.file("cameras.json");
    writeFileAtomic(cams, R"([{"id": 0, "img_name": "front", "width": 40, "height": 30, "position": [0, 0, -8],
       "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "fx": 40, "fy": 40}])");
    ASSERT_EQ(test::runCli("-q render " + model() + " --camera " + cams + " -o " + mDir.file("cam.png")), 0);
    EXPECT_EQ(readPng(mDir.file("cam.png")).width, 40);
    ASSERT_EQ(test::runCli("-q render " + model() + " --camera " + cams + " --size 20x15 -o " + mDir.file("half.png")), 0);
    EXPECT_EQ(readPng(mDir.file("half.png")).height, 15);

    const std::string bad = mDir.file("bad.json");
    writeFileAtomic(bad, "[{]");
    const std::string log = mDir.file("log.txt");
    EXPECT_EQ(test::runCli("render " + model() + " --camera " + bad + " -o " + mDir.file("x.png"), log), 1);
    EXPECT_NE(slurp(log).find("bad.json"), std::string::npos);
    EXPECT_FALSE(std::filesystem::exists(mDir.file("x.png")));
    EXPECT_EQ(test::runCli("render " + model() + " --orbit 2 -o " + mDir.file("x.png")), 2);
    for (const char* size : {"12", "99999999999x5", "16385x2", "0x4", "4x4junk", "+4x4", " 4x4", "4x"})
        EXPECT_EQ(test::runCli("render " + model() + " --size '" + size + "' -o " + mDir.file("x.png")), 2) << size;
    EXPECT_EQ(test::runCli("render " + model() + " --background 2,0,0 -o " + mDir.file("x.png")), 2);
    EXPECT_EQ(test::runCli("render " + model() + " --orbit 2 --camera " + cams + " -o " + mDir.file("d")), 2);
}

TEST_F(RenderCliTest, CompareReportsMetrics)
{
    const std::string a = mDir.file("a.png"), b = mDir.file("b.png"), out = mDir.file("out.txt");
    ASSERT_EQ(test::runCli("-q render " + model() + " -o " + a + " --size 32x32"), 0);
    ASSERT_EQ(test::runCli("-q render " + model() + " -o " + b + " --size 32x32 --elevation 30"), 0);
    ASSERT_EQ(test::runCli("compare " + a + " " + a + " --json", out), 0);
    EXPECT_NE(slurp(out).find("\"psnr\": null"), std::string::npos) << slurp(out);
    EXPECT_NE(slurp(out).find("\"ssim\": 1.0"), std::string::npos) << slurp(out);
    ASSERT_EQ(test::runCli("compare " + a + " " + b, out), 0);
    EXPECT_NE(slurp(out).find("PSNR"), std::string::npos);
    ASSERT_EQ(test::runCli("-q render " + model() + " -o " + b + " --size 16x32"), 0);
    EXPECT_EQ(test::runCli("compare " + a + " " + b, out), 1);
    EXPECT_NE(slurp(out).find("differ in size"), std::string::npos);
}

} // namespace
} // namespace splatwarp
