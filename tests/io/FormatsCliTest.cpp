/// `convert` writes every format by the output's extension and every model reader reads them back
/// (by content); broken files of each new reader make the CLI exit 1 naming the file.
#include <gtest/gtest.h>

#include <filesystem>

#include "PlyTestFiles.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

std::string fixture(const std::string& name) { return std::string(SPLATWARP_SOURCE_DIR) + "/tests/io/data/" + name; }

} // namespace

TEST(FormatsCli, ConvertWritesEachFormatAndReadsItBack)
{
    TempDir dir;
    const std::string src = fixture("random200-sh3.ply");
    for (const std::string out : {"m.ply", "m.compressed.ply", "m.splat", "m.spz", "m4.spz", "m.glb", "m.vdb"}) {
        const std::string flags = out == "m4.spz" ? " --spz-version 4" : out == "m.vdb" ? " --points" : "";
        ASSERT_EQ(runCli("-q convert " + src + " " + dir.file(out) + flags), 0) << out;
        ASSERT_EQ(runCli("-q convert " + dir.file(out) + " " + dir.file(out + ".ply")), 0) << out;
        const GaussianCloud back = readGaussians(dir.file(out + ".ply"));
        EXPECT_EQ(back.size(), 200u) << out;
        EXPECT_EQ(back.shDegree, out == "m.splat" ? 0 : 3) << out;
        EXPECT_EQ(runCli("-q info " + dir.file(out)), 0) << out;
    }
    EXPECT_EQ(runCli("-q convert " + src + " " + dir.file("m.xyz")), 2);
    EXPECT_EQ(runCli("-q convert " + src + " " + dir.file("m.spz") + " --spz-version 2"), 2);
    // A format's flags with another format's output, and seeds outside u64, are usage errors.
    EXPECT_EQ(runCli("-q convert " + src + " " + dir.file("x.ply") + " --spz-version 4"), 2);
    EXPECT_EQ(runCli("-q convert " + src + " " + dir.file("x.spz") + " --sog-seed 3"), 2);
    for (const char* seed : {"-1", "18446744073709551616", "1e3", "99999999999999999999"})
        EXPECT_EQ(runCli("-q convert " + src + " " + dir.file("x.sog") + " --sog-seed " + seed), 2) << seed;
    EXPECT_EQ(runCli("-q convert " + src + " " + dir.file("x.sog") + " --sog-seed 18446744073709551615"), 0);
}

TEST(FormatsCli, BrokenNewFormatsExitOneNamingTheFile)
{
    TempDir dir;
    const std::string spz4 = readBytes(fixture("random200-sh3.v4.spz")), glb = readBytes(fixture("random200-sh3.glb"));
    const std::pair<std::string, std::string> cases[] = {{"cut.spz", spz4.substr(0, spz4.size() / 2)},
                                                         {"cut.glb", glb.substr(0, glb.size() / 2)},
                                                         {"magic.glb", "glTF\x07" + glb.substr(5)}};
    for (const auto& [name, bytes] : cases) {
        writeBytes(dir.file(name), bytes);
        const std::string log = dir.file(name + ".log");
        EXPECT_EQ(runCli("convert " + dir.file(name) + " " + dir.file("out.ply"), log), 1) << name;
        EXPECT_NE(fileBytes(log).find(dir.file(name)), std::string::npos) << fileBytes(log);
    }
}

TEST(FormatsCli, SplatWriterRefusesWhatItsReaderWouldNotRead)
{
    // .splat has no magic: its reader refuses centres or scales beyond 1e7 as corrupt data, so the
    // writer refuses them too rather than write a file nothing reads back.
    TempDir dir;
    for (const bool farCentre : {true, false}) {
        GaussianCloud g = randomCloud(6, 0, 3);
        if (farCentre) g.means[3 * 4 + 1] = 4e7f;
        else g.logScales[3 * 4 + 2] = 30.0f; // e^30 ~ 1.1e13
        const std::string path = dir.file(farCentre ? "far.splat" : "big.splat");
        const std::string m = inputErrorMessage([&] { writeGaussians(path, g); });
        EXPECT_NE(m.find("cannot write .splat: Gaussian 4: "), std::string::npos) << m;
        EXPECT_NE(m.find(farCentre ? "position" : "scale"), std::string::npos) << m;
        EXPECT_FALSE(std::filesystem::exists(path));
    }
    GaussianCloud g = randomCloud(6, 0, 3);
    g.means[0] = 9e6f; // inside the bounds: written and read back
    writeGaussians(dir.file("ok.splat"), g);
    EXPECT_EQ(readGaussians(dir.file("ok.splat")).size(), 6u);
}
