#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "PlyTestFiles.h"
#include "io/CloudStats.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

GaussianCloud cloudWithInvalid()
{
    GaussianCloud g = randomCloud(5000, 2, 77);
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    g.means[3 * 10 + 1] = nan;
    g.opacities[20] = -inf;
    g.logScales[3 * 30 + 2] = inf;
    g.rotations[4 * 40] = nan;
    g.sh[50 * g.shStride() + 7] = nan;
    return g;
}

// Naive double-precision reference over the finite values.
CloudStats naiveStats(const GaussianCloud& g)
{
    CloudStats s;
    s.count = g.size();
    s.shDegree = g.shDegree;
    const double inf = std::numeric_limits<double>::infinity();
    double lo[3] = {inf, inf, inf}, hi[3] = {-inf, -inf, -inf};
    double opMin = inf, opMax = -inf, opSum = 0, qMin = inf, qMax = -inf;
    std::size_t opN = 0;
    std::vector<double> scales;
    for (std::size_t i = 0; i < g.size(); ++i) {
        const Vec3f p = g.mean(i);
        if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
            for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], double(p[a])), hi[a] = std::max(hi[a], double(p[a]));
        if (std::isfinite(g.opacities[i])) {
            const double al = 1.0 / (1.0 + std::exp(-double(g.opacities[i])));
            opMin = std::min(opMin, al), opMax = std::max(opMax, al), opSum += al, ++opN;
        }
        const Quatf q = g.rotation(i);
        const double n = std::sqrt(double(q.w) * q.w + double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z);
        if (std::isfinite(n)) qMin = std::min(qMin, n), qMax = std::max(qMax, n);
        for (int a = 0; a < 3; ++a)
            if (std::isfinite(g.logScales[3 * i + a])) scales.push_back(std::exp(double(g.logScales[3 * i + a])));
    }
    std::sort(scales.begin(), scales.end());
    s.bboxMin = Vec3d(lo[0], lo[1], lo[2]);
    s.bboxMax = Vec3d(hi[0], hi[1], hi[2]);
    s.opacityMin = opMin, s.opacityMax = opMax, s.opacityMean = opSum / double(opN);
    s.quatNormMin = qMin, s.quatNormMax = qMax;
    s.scaleMin = scales.front(), s.scaleMax = scales.back(), s.scaleMedian = scales[(scales.size() - 1) / 2];
    for (const auto* arr : {&g.means, &g.rotations, &g.logScales, &g.opacities, &g.sh})
        for (float v : *arr) s.invalidValues += std::isfinite(v) ? 0 : 1;
    return s;
}

void expectNear(const CloudStats& a, const CloudStats& b)
{
    EXPECT_EQ(a.count, b.count);
    EXPECT_EQ(a.shDegree, b.shDegree);
    for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(a.bboxMin[k], b.bboxMin[k]);
        EXPECT_EQ(a.bboxMax[k], b.bboxMax[k]);
    }
    EXPECT_EQ(a.opacityMin, b.opacityMin);
    EXPECT_EQ(a.opacityMax, b.opacityMax);
    EXPECT_NEAR(a.opacityMean, b.opacityMean, 1e-12); // summation order only
    EXPECT_EQ(a.scaleMin, b.scaleMin);
    EXPECT_EQ(a.scaleMedian, b.scaleMedian);
    EXPECT_EQ(a.scaleMax, b.scaleMax);
    EXPECT_NEAR(a.quatNormMin, b.quatNormMin, 1e-15);
    EXPECT_NEAR(a.quatNormMax, b.quatNormMax, 1e-15);
    EXPECT_EQ(a.invalidValues, b.invalidValues);
}

} // namespace

TEST(CloudStats, MatchesNaiveReferenceSerialAndThreaded)
{
    const GaussianCloud g = cloudWithInvalid();
    const CloudStats ref = naiveStats(g);
    EXPECT_EQ(ref.invalidValues, 5u);
    expectNear(computeCloudStats(g, false), ref);
    expectNear(computeCloudStats(g, true), ref);
}

TEST(CloudStats, EmptyCloudIsAllZero)
{
    const CloudStats s = computeCloudStats(GaussianCloud{});
    EXPECT_EQ(s.count, 0u);
    EXPECT_EQ(s.bboxMax.x, 0.0);
    EXPECT_EQ(s.opacityMean, 0.0);
    EXPECT_EQ(s.scaleMedian, 0.0);
}

TEST(CloudStats, InfoJsonReportsFileWithInvalidValues)
{
    TempDir dir;
    const GaussianCloud g = cloudWithInvalid();
    const std::string path = dir.file("bad.ply");
    PlyVariant v;
    v.format = "binary_big_endian";
    writeBytes(path, plyBytes(g, v));
    const CloudStats ref = naiveStats(g);

    const std::string out = dir.file("info.json");
    ASSERT_EQ(runCli("-q info --json " + path, out), 0) << readBytes(out);
    const nlohmann::json j = nlohmann::json::parse(readBytes(out));
    EXPECT_EQ(j.at("count").get<std::size_t>(), g.size());
    EXPECT_EQ(j.at("shDegree").get<int>(), 2);
    EXPECT_EQ(j.at("format").get<std::string>(), "ply-binary-be");
    EXPECT_EQ(j.at("invalidValues").get<std::size_t>(), 5u);
    for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(j.at("bboxMin").at(k).get<double>(), ref.bboxMin[k]);
        EXPECT_EQ(j.at("bboxMax").at(k).get<double>(), ref.bboxMax[k]);
    }
    EXPECT_EQ(j.at("scale").at("median").get<double>(), ref.scaleMedian);
    EXPECT_NEAR(j.at("opacity").at("mean").get<double>(), ref.opacityMean, 1e-12);
    EXPECT_EQ(j.at("quatNorm").at("max").get<double>(), ref.quatNormMax);

    // --drop-invalid: the 5 broken Gaussians are gone before the statistics.
    ASSERT_EQ(runCli("-q info --json --drop-invalid " + path, out), 0);
    const nlohmann::json d = nlohmann::json::parse(readBytes(out));
    EXPECT_EQ(d.at("count").get<std::size_t>(), g.size() - 5);
    EXPECT_EQ(d.at("dropped").get<std::size_t>(), 5u);
    EXPECT_EQ(d.at("invalidValues").get<std::size_t>(), 0u);

    // Plain text output names the essentials.
    ASSERT_EQ(runCli("-q info " + path, out), 0);
    const std::string text = readBytes(out);
    EXPECT_NE(text.find("count:           5000"), std::string::npos) << text;
    EXPECT_NE(text.find("invalid values:  5"), std::string::npos) << text;
    EXPECT_NE(text.find("unusable:        5 Gaussians"), std::string::npos) << text;

    // Finite but unusable (a log-scale past 40): no NaN to count, still named in the text.
    GaussianCloud wide = randomCloud(50, 0, 9);
    wide.logScales[3 * 7] = 50.0f;
    writeBytes(path, plyBytes(wide, v));
    ASSERT_EQ(runCli("-q info " + path, out), 0);
    const std::string wideText = readBytes(out);
    EXPECT_NE(wideText.find("invalid values:  0"), std::string::npos) << wideText;
    EXPECT_NE(wideText.find("unusable:        1 Gaussians"), std::string::npos) << wideText;
}

TEST(CloudStats, ConvertSplatEqualsDirectRead)
{
    SPLATWARP_REQUIRE_DATA(splat, "splats/lastchance.splat");
    TempDir dir;
    const std::string out = dir.file("plant.ply");
    ASSERT_EQ(runCli("-q convert " + splat + " " + out), 0);
    EXPECT_TRUE(sameBits(readGaussians(splat), readGaussians(out)));
}

// A model whose linear scales were written where log scales belong: every Gaussian a giant, and the
// warning names that likely cause instead of suggesting to drop them all.
TEST(CloudStats, MostlyGiantsPointAtLinearScales)
{
    GaussianCloud g = randomCloud(2000, 0, 5);
    for (float& v : g.means) v *= 0.25f;                       // a bulk about 1 wide
    for (float& v : g.logScales) v = std::exp(-3.5f + 0.5f * v); // sigma 0.02-0.05 stored as logs: e^0.03
    std::vector<CloudWarning> w = outlierWarnings(g);
    ASSERT_EQ(w.size(), 1u);
    EXPECT_EQ(w[0].kind, "giant-gaussians");
    EXPECT_EQ(w[0].count, 2000u);
    EXPECT_NE(w[0].message.find("2000 of the 2000 Gaussians are wider than half the bulk"), std::string::npos) << w[0].message;
    EXPECT_NE(w[0].message.find("linear scales where log scales belong"), std::string::npos) << w[0].message;
    for (float& v : g.logScales) v = std::log(v); // the scales as they were meant
    EXPECT_TRUE(outlierWarnings(g).empty());
}

// Far floaters and giants: info warns of them, convert --drop-outliers drops exactly them, deform
// warns and reports them (core/Outliers.h is tested on its own in tests/core).
TEST(CloudStats, OutliersAreWarnedOfAndDropped)
{
    TempDir dir;
    GaussianCloud g = randomCloud(3000, 1, 21);
    for (float& v : g.logScales) v = -3.0f + 0.5f * v; // sigma 0.02-0.14 in a bulk about 4 wide
    std::vector<std::uint8_t> planted(g.size(), 0);
    for (std::size_t i = 100; i < 3000; i += 300) {
        g.setMean(i, Vec3f(float(i) * 0.05f, -40.0f, 3.0f));
        planted[i] = 1;
    }
    for (std::size_t i = 50; i < 3000; i += 1000) { // sigma 50
        g.logScales[3 * i + 1] = std::log(50.0f);
        planted[i] = 1;
    }
    const std::string path = dir.file("floaters.ply");
    writePly(path, g);

    const std::string out = dir.file("out.txt");
    ASSERT_EQ(runCli("-q info --json " + path, out), 0) << readBytes(out);
    const nlohmann::json j = nlohmann::json::parse(readBytes(out));
    std::size_t far = 0, giants = 0;
    for (const auto& w : j.at("warnings")) {
        if (w.at("kind") == "far-centres") far = w.at("count").get<std::size_t>();
        if (w.at("kind") == "giant-gaussians") giants = w.at("count").get<std::size_t>();
    }
    EXPECT_EQ(far, 10u) << j.dump();
    EXPECT_EQ(giants, 3u) << j.dump();

    const std::string clean = dir.file("clean.ply");
    ASSERT_EQ(runCli("convert --drop-outliers " + path + " " + clean, out), 0) << readBytes(out);
    EXPECT_NE(readBytes(out).find("dropped 13 outliers: 10 whose centres"), std::string::npos) << readBytes(out);
    GaussianCloud kept = g;
    kept.erase(planted);
    EXPECT_TRUE(sameBits(readGaussians(clean), kept));
    ASSERT_EQ(runCli("-q info --json " + clean, out), 0);
    EXPECT_EQ(readBytes(out).find("far-centres"), std::string::npos) << readBytes(out);
    EXPECT_EQ(readBytes(out).find("giant-gaussians"), std::string::npos) << readBytes(out);

    const std::string spec = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json";
    ASSERT_EQ(runCli("deform " + path + " --spec " + spec + " -o " + dir.file("d") + " --stage1-only --device cpu", out), 0)
        << readBytes(out);
    EXPECT_NE(readBytes(out).find("10 Gaussians lie far from the rest"), std::string::npos) << readBytes(out);
    const nlohmann::json report = nlohmann::json::parse(readBytes(dir.file("d/report.json")));
    ASSERT_EQ(report.at("input").at("warnings").size(), 2u) << report.at("input").dump();
    EXPECT_EQ(report.at("input").at("warnings")[0].at("kind"), "far-centres");
    EXPECT_EQ(report.at("input").at("warnings")[0].at("count"), 10u);
    EXPECT_EQ(report.at("input").at("warnings")[1].at("kind"), "giant-gaussians");
    EXPECT_EQ(report.at("input").at("warnings")[1].at("count"), 3u);
}
