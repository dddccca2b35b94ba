/// Real third-party files (../shared/data/splats): round trips and an independent parse.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <sstream>

#include "PlyTestFiles.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

// Header lines and body of a PLY, split naively at "end_header\n".
void splitPly(const std::string& bytes, std::vector<std::string>& lines, std::string& body)
{
    const std::size_t end = bytes.find("end_header\n");
    ASSERT_NE(end, std::string::npos);
    std::istringstream in(bytes.substr(0, end));
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    body = bytes.substr(end + 11);
}

} // namespace

TEST(DataRoundTrip, EveryPlyReadWriteReadIsBitExact)
{
    SPLATWARP_REQUIRE_DATA(dir, "splats");
    TempDir tmp;
    int files = 0, bodyCompared = 0;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        if (entry.path().extension() != ".ply") continue;
        const std::string path = entry.path().string();
        SCOPED_TRACE(path);
        // guitar.decoded.ply holds +Inf opacities (alpha 255 decoded without a clamp): drop them.
        ReadOptions options;
        options.dropInvalid = true;
        ReadReport report;
        const GaussianCloud g = readGaussians(path, options, &report);
        const std::string out = tmp.file("out.ply");
        writePly(out, g);
        const GaussianCloud back = readGaussians(out);
        EXPECT_TRUE(sameBits(g, back));
        ++files;

        // Files already in exact graphdeco layout come back byte for byte.
        std::vector<std::string> lines, outLines;
        std::string body, outBody;
        const std::string original = readBytes(path);
        splitPly(original, lines, body);
        splitPly(readBytes(out), outLines, outBody);
        if (lines == outLines && report.dropped == 0) {
            EXPECT_TRUE(body == outBody);
            ++bodyCompared;
        }
    }
    EXPECT_GE(files, 6);
    EXPECT_GE(bodyCompared, 3); // train-1000, playbot, lastchance.decoded
}

TEST(DataRoundTrip, Train1000MatchesNaiveParse)
{
    SPLATWARP_REQUIRE_DATA(path, "splats/train-1000.ply");
    const std::string bytes = readBytes(path);
    std::vector<std::string> lines;
    std::string body;
    splitPly(bytes, lines, body);
    std::vector<std::string> names;
    std::size_t count = 0;
    for (const std::string& l : lines) {
        std::istringstream in(l);
        std::string a, b, c;
        in >> a >> b >> c;
        if (a == "element") count = std::stoul(c);
        if (a == "property") names.push_back(c);
    }
    ASSERT_EQ(body.size(), count * names.size() * 4);
    const auto raw = [&](std::size_t i, const std::string& name) {
        const std::size_t p = std::size_t(std::find(names.begin(), names.end(), name) - names.begin());
        float v;
        std::memcpy(&v, body.data() + 4 * (i * names.size() + p), 4);
        return v;
    };
    const GaussianCloud g = readGaussians(path);
    ASSERT_EQ(g.size(), count);
    ASSERT_EQ(g.shDegree, 3);
    for (std::size_t i = 0; i < count; ++i) {
        EXPECT_EQ(g.means[3 * i + 0], raw(i, "x"));
        EXPECT_EQ(g.means[3 * i + 2], raw(i, "z"));
        EXPECT_EQ(g.opacities[i], raw(i, "opacity"));
        for (int a = 0; a < 3; ++a) EXPECT_EQ(g.logScales[3 * i + a], raw(i, "scale_" + std::to_string(a)));
        for (int a = 0; a < 4; ++a) EXPECT_EQ(g.rotations[4 * i + a], raw(i, "rot_" + std::to_string(a)));
        for (int c = 0; c < 3; ++c) {
            EXPECT_EQ(g.sh[48 * i + c], raw(i, "f_dc_" + std::to_string(c)));
            for (int j = 1; j < 16; ++j) // 15 rest coefficients per channel, channel-major
                EXPECT_EQ(g.sh[48 * i + 3 * j + c], raw(i, "f_rest_" + std::to_string(c * 15 + j - 1)));
        }
    }
}
