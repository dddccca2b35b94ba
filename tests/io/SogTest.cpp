/// SOG (PlayCanvas meta.json version 2 + lossless WebP): round trips within the quantisation the
/// format's bit depths give (derived below), deterministic bytes, the folder form, and bad input
/// (truncated, wrong content, huge counts, NaN, mismatched images, WebP and zip bombs, paths
/// leaving the folder) refused with InputError naming the file.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tbb/task_arena.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <set>

#include "PlyTestFiles.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/FormatReaders.h"
#include "io/GaussianIO.h"
#include "io/SogFormat.h"
#include "io/SogIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;
using Files = std::vector<std::pair<std::string, std::string>>;

namespace {

double logOf(double x) { return x < 0 ? -std::log1p(-x) : std::log1p(x); }
double sigmoidD(double x) { return 1 / (1 + std::exp(-x)); }

std::string& fileIn(Files& files, const std::string& name)
{
    for (auto& f : files)
        if (f.first == name) return f.second;
    throw std::runtime_error("no " + name);
}

// A bundle whose meta.json has been edited.
std::string withMeta(Files files, const std::function<void(nlohmann::json&)>& edit)
{
    nlohmann::json meta = nlohmann::json::parse(fileIn(files, "meta.json"));
    edit(meta);
    fileIn(files, "meta.json") = meta.dump();
    return sog::storedZip(files);
}

// The reader's message for a bundle, written to disk and read by path.
std::string errorOf(const TempDir& dir, const std::string& bytes)
{
    const std::string path = dir.file("bad.sog");
    writeBytes(path, bytes);
    const std::string m = inputErrorMessage([&] { readGaussians(path); });
    EXPECT_NE(m.find(path), std::string::npos) << m;
    return m;
}

// Position: the log-encoded coordinate is rounded to a 16-bit grid of step D = (max - min) / 65535,
// so |t - t'| <= D / 2, and x = sign(t)(e^|t| - 1) moves at most (|x| + 1)(e^(D/2) - 1).
// Rotation: stored q sqrt2 in [-1, 1] on 255 steps: |q - q'| <= d = 1 / (255 sqrt2); the derived
// component as in SpzReaderTest: sqrt(2 sqrt3 d + 3 d^2). Alpha: half an 8-bit step.
void expectWithinQuantisation(const GaussianCloud& src, const GaussianCloud& dec)
{
    const std::vector<std::size_t> order = compressedPlyOrder(src);
    double lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
        lo[a] = hi[a] = logOf(src.means[a]);
        for (std::size_t i = 0; i < src.size(); ++i) {
            lo[a] = std::min(lo[a], logOf(src.means[3 * i + a]));
            hi[a] = std::max(hi[a], logOf(src.means[3 * i + a]));
        }
    }
    const double d = 1 / (255 * std::sqrt(2.0)), derived = std::sqrt(2 * std::sqrt(3.0) * d + 3 * d * d);
    for (std::size_t t = 0; t < dec.size(); ++t) {
        const std::size_t i = order[t];
        for (int a = 0; a < 3; ++a) {
            const double x = src.means[3 * i + a];
            const double tol = (std::fabs(x) + 1) * std::expm1((hi[a] - lo[a]) / 65535 / 2) + 1e-6;
            ASSERT_NEAR(dec.means[3 * t + a], x, tol) << "Gaussian " << i << " axis " << a;
        }
        double q[4], n = 0, dot = 0;
        for (int a = 0; a < 4; ++a) n += double(src.rotations[4 * i + a]) * src.rotations[4 * i + a];
        for (int a = 0; a < 4; ++a) dot += (q[a] = src.rotations[4 * i + a] / std::sqrt(n)) * dec.rotations[4 * t + a];
        for (int a = 0; a < 4; ++a)
            ASSERT_NEAR((dot < 0 ? -1 : 1) * q[a], dec.rotations[4 * t + a], derived + 1e-6) << "Gaussian " << i;
        ASSERT_NEAR(sigmoidD(src.opacities[i]), sigmoidD(dec.opacities[t]), 0.5 / 255 + 2e-6) << "Gaussian " << i;
    }
}

// Codebook values: every decoded value is one of 256, and 1-D k-means over values spread over a
// range R is at least as good on average as a uniform 256-level quantiser (mean error R / 1024);
// no value is further than one uniform step R / 256 from its entry.
void expectCodebookError(const std::vector<double>& src, const std::vector<double>& dec, double range)
{
    double sum = 0, worst = 0;
    for (std::size_t k = 0; k < src.size(); ++k) {
        sum += std::fabs(src[k] - dec[k]);
        worst = std::max(worst, std::fabs(src[k] - dec[k]));
    }
    EXPECT_LE(sum / double(src.size()), range / 1024);
    EXPECT_LE(worst, range / 256);
}

void expectCodebooksClose(const GaussianCloud& src, const GaussianCloud& dec)
{
    const std::vector<std::size_t> order = compressedPlyOrder(src);
    std::vector<double> s, d, sc, dc;
    for (std::size_t t = 0; t < dec.size(); ++t)
        for (int a = 0; a < 3; ++a) {
            s.push_back(src.logScales[3 * order[t] + a]);
            d.push_back(dec.logScales[3 * t + a]);
            sc.push_back(src.shOf(order[t])[a]);
            dc.push_back(dec.shOf(t)[a]);
        }
    expectCodebookError(s, d, 4.0); // randomCloud: uniform in [-2, 2]
    expectCodebookError(sc, dc, 4.0);
}

} // namespace

TEST(SogTest, BundleRoundTripWithinQuantisationForEveryShDegree)
{
    TempDir dir;
    for (int degree = 0; degree <= 3; ++degree) {
        const GaussianCloud src = randomCloud(700, degree, 40 + unsigned(degree));
        const std::string path = dir.file("m" + std::to_string(degree) + ".sog");
        writeGaussians(path, src);
        ReadReport report;
        const GaussianCloud dec = readGaussians(path, {}, &report);
        EXPECT_EQ(report.format, "sog");
        ASSERT_EQ(dec.size(), src.size());
        ASSERT_EQ(dec.shDegree, degree);
        expectWithinQuantisation(src, dec);
        expectCodebooksClose(src, dec);
    }
}

// With at most 256 distinct values a codebook is exact, and with fewer distinct SH vectors than
// palette entries k-means finds each one: f_dc and f_rest come back bit for bit, also under alpha
// 0 (a lossless WebP encoder may drop the RGB of transparent texels unless told to keep it).
TEST(SogTest, FewDistinctColoursComeBackExactly)
{
    GaussianCloud src = randomCloud(500, 3, 7);
    const GaussianCloud palette = randomCloud(5, 3, 8); // 5 SH vectors of 48 values: 240 distinct
    for (std::size_t i = 0; i < src.size(); ++i) {
        std::copy_n(palette.shOf(i % 5), src.shStride(), src.shOf(i));
        if (i % 7 == 0) src.opacities[i] = -30; // alpha 0 in sh0.webp
    }
    const GaussianCloud dec = readGaussiansFromBytes("m.sog", encodeSog("m.sog", src));
    const std::vector<std::size_t> order = compressedPlyOrder(src);
    for (std::size_t t = 0; t < dec.size(); ++t)
        for (int k = 0; k < src.shStride(); ++k)
            ASSERT_EQ(dec.shOf(t)[k], src.shOf(order[t])[k]) << "Gaussian " << order[t] << " SH value " << k;
}

TEST(SogTest, SameInputAndSeedGiveSameBytes)
{
    const GaussianCloud src = randomCloud(600, 2, 3);
    SogOptions a, b;
    b.seed = 2;
    const std::string first = encodeSog("m.sog", src, a);
    EXPECT_EQ(first, encodeSog("m.sog", src, a));
    EXPECT_NE(first, encodeSog("m.sog", src, b)); // the seed does reach the palette
}

// The palette's labels are what a scan over every centroid gives (the lowest index of the least
// float sum of squares, summed in dimension order): the ranking by matrix product only narrows
// the scan. Ties (repeated points, so repeated centroids), points between two centroids, data far
// from the origin (large |x| against small distances), more centroids than a block of points, and
// every point a centroid (the midpoints, moved by a few float steps, then lie between two of them).
TEST(SogTest, PaletteLabelsAreTheScansNearestCentroid)
{
    std::mt19937 rng(11);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    struct Case {
        std::size_t n, k;
        int dims;
        float offset, spread;
    };
    for (const Case& c : {Case{3000, 256, 9, 0.0f, 1.0f}, Case{2000, 4096, 24, 0.0f, 0.05f},
                          Case{2500, 512, 45, 1000.0f, 0.01f}, Case{1500, 64, 3, -5.0f, 1e-6f}, Case{800, 800, 9, 0.0f, 1.0f},
                          Case{800, 800, 24, 3.0f, 0.001f}}) {
        std::vector<float> points(c.n * std::size_t(c.dims));
        for (float& v : points) v = c.offset + c.spread * noise(rng);
        for (std::size_t i = c.n / 2; i < c.n; i += 3) // repeats, and midpoints of two points
            for (int j = 0; j < c.dims; ++j) {
                const std::size_t a = (i * 7) % (c.n / 2), b = (i * 13 + 1) % (c.n / 2);
                points[i * std::size_t(c.dims) + std::size_t(j)] = i % 2 ? points[a * std::size_t(c.dims) + std::size_t(j)]
                    : 0.5f * (points[a * std::size_t(c.dims) + std::size_t(j)] + points[b * std::size_t(c.dims) + std::size_t(j)]) +
                        1e-7f * c.spread * noise(rng);
            }
        for (int iterations : {0, 2, 8}) { // later rounds spare up to 70% of the points here
            const sog::Palette p = sog::kmeans(points, c.n, c.dims, c.k, iterations, 5);
            std::size_t wrong = 0;
            for (std::size_t i = 0; i < c.n; ++i) {
                const float* x = &points[i * std::size_t(c.dims)];
                float best = std::numeric_limits<float>::infinity();
                std::uint32_t label = 0;
                for (std::size_t k = 0; k < p.count; ++k) {
                    float s = 0;
                    for (int j = 0; j < c.dims; ++j) {
                        const float diff = x[j] - p.centroids[k * std::size_t(c.dims) + std::size_t(j)];
                        s += diff * diff;
                    }
                    if (s < best) best = s, label = std::uint32_t(k);
                }
                wrong += p.labels[i] != label;
            }
            EXPECT_EQ(wrong, 0u) << c.n << " points of " << c.dims << " dims, " << c.k << " centroids, offset "
                                 << c.offset << ", " << iterations << " iterations";
        }
    }
}

// Past 4096 entries a label is the nearest centroid among those of the groups near its own group:
// on clustered data nearly every label is still the scan's nearest, twice the entries fit the
// points better, and the palette does not depend on the thread count.
TEST(SogTest, LargePalettesLabelNearlyEveryPointWithItsNearestCentroid)
{
    constexpr std::size_t n = 24000, centres = 3000;
    constexpr int dims = 24;
    std::mt19937 rng(17);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    std::vector<float> centre(centres * dims), points(n * dims);
    for (float& v : centre) v = noise(rng);
    for (std::size_t i = 0; i < n; ++i)
        for (int j = 0; j < dims; ++j) points[i * dims + j] = centre[(i % centres) * dims + j] + 0.1f * noise(rng);
    const auto squared = [&](const sog::Palette& p, std::size_t i, std::size_t c) {
        float s = 0;
        for (int j = 0; j < dims; ++j) s += (points[i * dims + j] - p.centroids[c * dims + j]) * (points[i * dims + j] - p.centroids[c * dims + j]);
        return s;
    };
    const auto error = [&](const sog::Palette& p) {
        double sum = 0;
        for (std::size_t i = 0; i < n; ++i) sum += squared(p, i, p.labels[i]);
        return sum / double(n);
    };
    const sog::Palette large = sog::kmeans(points, n, dims, 8192, 6, 3);
    ASSERT_EQ(large.count, 8192u);
    std::size_t wrong = 0, checked = 0;
    for (std::size_t i = 0; i < n; i += 7, ++checked) {
        std::uint32_t nearest = 0;
        for (std::size_t c = 1; c < large.count; ++c)
            if (squared(large, i, c) < squared(large, i, nearest)) nearest = std::uint32_t(c);
        wrong += squared(large, i, large.labels[i]) > squared(large, i, nearest);
    }
    EXPECT_LT(wrong, checked / 200) << wrong << " of " << checked << " points not with their nearest centroid";
    EXPECT_LT(error(large), 0.8 * error(sog::kmeans(points, n, dims, 4096, 6, 3)));
    tbb::task_arena one(1);
    one.execute([&] {
        const sog::Palette serial = sog::kmeans(points, n, dims, 8192, 6, 3);
        EXPECT_EQ(serial.labels, large.labels);
        EXPECT_EQ(serial.centroids, large.centroids);
    });
}

// By default the palette has splat-transform's size, the largest power of two <= n (up to 64 K);
// --sog-palette caps it.
TEST(SogTest, DefaultPaletteIsSplatTransformsSize)
{
    const GaussianCloud cloud = randomCloud(9000, 1, 4);
    const auto count = [&](const SogOptions& o) {
        Files files = encodeSogFiles("m.sog", cloud, o);
        return nlohmann::json::parse(fileIn(files, "meta.json"))["shN"]["count"];
    };
    EXPECT_EQ(count({}), 8192);
    SogOptions capped;
    capped.maxPalette = 4096;
    EXPECT_EQ(count(capped), 4096);
}

TEST(SogTest, FolderFormReadsAsTheBundle)
{
    TempDir dir;
    const GaussianCloud src = randomCloud(300, 1, 5);
    writeSog(dir.file("m.sog"), src);
    writeSog(dir.file("meta.json"), src);
    for (const char* f : {"means_l.webp", "means_u.webp", "quats.webp", "scales.webp", "sh0.webp", "shN_centroids.webp",
                          "shN_labels.webp"})
        EXPECT_TRUE(std::filesystem::is_regular_file(dir.file(f))) << f;
    const GaussianCloud bundle = readGaussians(dir.file("m.sog"));
    for (const std::string& p : {dir.file("meta.json"), dir.path().string()}) {
        const GaussianCloud folder = readGaussians(p);
        ASSERT_EQ(folder.size(), bundle.size());
        for (std::size_t i = 0; i < bundle.size(); ++i) ASSERT_TRUE(folder.sameGaussian(i, bundle, i)) << p << " " << i;
    }
}

TEST(SogTest, ConvertWritesBundleAndFolderAndRefusesBadInputWithExit1)
{
    TempDir dir;
    writePly(dir.file("in.ply"), randomCloud(200, 2, 9));
    EXPECT_EQ(runCli("convert " + dir.file("in.ply") + " " + dir.file("out.sog")), 0);
    EXPECT_EQ(runCli("convert " + dir.file("in.ply") + " " + dir.file("folder/meta.json")), 0);
    EXPECT_EQ(readGaussians(dir.file("out.sog")).size(), 200u);
    EXPECT_EQ(readGaussians(dir.file("folder")).size(), 200u);
    // The same folder again from an SH-0 model: the SH images of the first export go with it.
    ASSERT_TRUE(std::filesystem::exists(dir.file("folder/shN_labels.webp")));
    writePly(dir.file("sh0.ply"), randomCloud(50, 0, 4));
    EXPECT_EQ(runCli("convert " + dir.file("sh0.ply") + " " + dir.file("folder/meta.json")), 0);
    EXPECT_FALSE(std::filesystem::exists(dir.file("folder/shN_labels.webp")));
    EXPECT_FALSE(std::filesystem::exists(dir.file("folder/shN_centroids.webp")));
    EXPECT_EQ(readGaussians(dir.file("folder")).size(), 50u);
    const std::string bytes = fileBytes(dir.file("out.sog"));
    writeBytes(dir.file("cut.sog"), bytes.substr(0, bytes.size() / 2));
    EXPECT_EQ(runCli("convert " + dir.file("cut.sog") + " " + dir.file("x.ply"), dir.file("log.txt")), 1);
    EXPECT_NE(fileBytes(dir.file("log.txt")).find("cut.sog"), std::string::npos);
    EXPECT_FALSE(std::filesystem::exists(dir.file("x.ply")));
}

TEST(SogTest, TruncatedOrNonSogZipIsRefused)
{
    TempDir dir;
    const std::string good = encodeSog("m.sog", randomCloud(100, 1, 2));
    EXPECT_NE(errorOf(dir, good.substr(0, good.size() - 30)).find("zip"), std::string::npos);
    EXPECT_NE(errorOf(dir, good.substr(0, 200)).find("zip"), std::string::npos);
    EXPECT_NE(errorOf(dir, sog::storedZip({{"readme.txt", "hello"}})).find("without meta.json"), std::string::npos);
    std::string flipped = good; // a bit flipped in the first image: the CRC catches it
    flipped[60] = char(flipped[60] ^ 0x10);
    EXPECT_NE(errorOf(dir, flipped).find("CRC"), std::string::npos);
}

TEST(SogTest, BadMetaJsonIsRefused)
{
    TempDir dir;
    const Files files = encodeSogFiles("m.sog", randomCloud(100, 1, 2));
    const auto expect = [&](const std::function<void(nlohmann::json&)>& edit, const std::string& what) {
        EXPECT_NE(errorOf(dir, withMeta(files, edit)).find(what), std::string::npos) << what;
    };
    expect([](nlohmann::json& m) { m["version"] = 3; }, "version 3");
    expect([](nlohmann::json& m) { m.erase("version"); }, "version 1");
    expect([](nlohmann::json& m) { m["sh0"]["codebook"][7] = nullptr; }, "sh0.codebook[7] is not a number");
    expect([](nlohmann::json& m) { m["means"]["mins"] = {0, 0}; }, "means.mins must be an array of 3");
    expect([](nlohmann::json& m) { m["means"]["maxs"][1] = 1e6; }, "beyond 1e15");
    expect([](nlohmann::json& m) { m["count"] = 1e12; }, "count is");
    expect([](nlohmann::json& m) { m["shN"]["bands"] = 4; }, "shN.bands");
    expect([](nlohmann::json& m) { m["quats"]["files"] = {"../quats.webp"}; }, "plain file names");
    Files nan = files; // JSON has no NaN: a writer that prints one makes invalid JSON
    std::string& meta = fileIn(nan, "meta.json");
    meta.replace(meta.find("\"mins\":[") + 8, 0, "NaN,");
    EXPECT_NE(errorOf(dir, sog::storedZip(nan)).find("not valid JSON"), std::string::npos);
}

TEST(SogTest, CountsAndImageSizesThatDisagreeAreRefused)
{
    TempDir dir;
    const Files files = encodeSogFiles("m.sog", randomCloud(100, 1, 2)); // 12x12 images
    EXPECT_NE(errorOf(dir, withMeta(files, [](nlohmann::json& m) { m["count"] = 145; })).find("do not fit count 145"),
              std::string::npos);
    EXPECT_NE(errorOf(dir, withMeta(files, [](nlohmann::json& m) { m["count"] = 1000000; })).find("decompression bomb"),
              std::string::npos);
    Files other = files; // sh0 of another model's size
    Files larger = encodeSogFiles("n.sog", randomCloud(400, 1, 2));
    fileIn(other, "sh0.webp") = fileIn(larger, "sh0.webp");
    EXPECT_NE(errorOf(dir, sog::storedZip(other)).find("sh0.webp is 20x20, but means_l.webp is 12x12"), std::string::npos);
    Files notWebp = files;
    fileIn(notWebp, "quats.webp") = std::string(300, 'x');
    EXPECT_NE(errorOf(dir, sog::storedZip(notWebp)).find("quats.webp: not a WebP"), std::string::npos);
}

// A constant image compresses to almost nothing: its declared size is checked before decoding.
TEST(SogTest, WebpAndZipBombsAreRefusedBeforeDecoding)
{
    TempDir dir;
    Files files = encodeSogFiles("m.sog", randomCloud(100, 0, 2));
    sog::Image huge;
    huge.width = huge.height = 2048;
    huge.rgba.assign(std::size_t(2048) * 2048 * 4, 7);
    const std::string bomb = sog::encodeWebp(huge);
    ASSERT_LT(bomb.size(), 100000u);
    for (const char* f : {"means_l.webp", "means_u.webp", "quats.webp", "scales.webp", "sh0.webp"}) fileIn(files, f) = bomb;
    EXPECT_NE(errorOf(dir, withMeta(files, [](nlohmann::json& m) { m["count"] = 100; })).find("2048x2048 texels do not fit"),
              std::string::npos);
    // A zip entry that claims to inflate to 2 GiB: refused from the directory, nothing inflated.
    std::string zip = sog::storedZip(encodeSogFiles("m.sog", randomCloud(100, 0, 2)));
    const std::size_t central = zip.find(std::string("PK\1\2", 4));
    zip[central + 10] = 8; // deflate
    for (int b = 0; b < 4; ++b) zip[central + 24 + std::size_t(b)] = b == 3 ? char(0x7f) : char(0xff);
    EXPECT_NE(errorOf(dir, zip).find("more than the"), std::string::npos);
}

TEST(SogTest, FolderReadStaysInsideItsFolder)
{
    TempDir dir;
    std::filesystem::create_directories(dir.file("a"));
    writeSog(dir.file("a/meta.json"), randomCloud(100, 0, 2));
    std::filesystem::rename(dir.file("a/quats.webp"), dir.file("quats.webp"));
    std::filesystem::create_symlink(dir.file("quats.webp"), dir.file("a/quats.webp"));
    const std::string m = inputErrorMessage([&] { readGaussians(dir.file("a/meta.json")); });
    EXPECT_NE(m.find("quats.webp: not a regular file"), std::string::npos) << m;
}

namespace {

std::string fixture(const std::string& name) { return std::string(SPLATWARP_SOURCE_DIR) + "/tests/io/data/" + name; }

// The source Gaussian of each decoded one: splat-transform's Morton order refines crowded cells, so
// it differs from ours; centres are unique enough in random200 to pair them up (nearest centre).
std::vector<std::size_t> nearestSource(const GaussianCloud& src, const GaussianCloud& dec)
{
    std::vector<std::size_t> match(dec.size());
    for (std::size_t t = 0; t < dec.size(); ++t) {
        double best = 1e300;
        for (std::size_t i = 0; i < src.size(); ++i) {
            double d = 0;
            for (int a = 0; a < 3; ++a) d += std::pow(double(dec.means[3 * t + a]) - src.means[3 * i + a], 2);
            if (d < best) best = d, match[t] = i;
        }
    }
    return match;
}

// The codebook entry nearest to v: what both writers store for a codebook value.
float nearestEntry(const std::vector<float>& book, float v)
{
    float best = book[0];
    for (float e : book)
        if (std::fabs(e - v) < std::fabs(best - v)) best = e;
    return best;
}

} // namespace

// splat-transform 3.10.2's own bundle (tests/io/data/README.md): it truncates where we round, so a
// centre is off by up to one 16-bit step (bound (|x| + 1)(e^D - 1)), alpha by one 8-bit level, each
// stored quaternion component by 2 / (255 sqrt2); log scales and f_dc are the entry of its codebook
// nearest to the source value, except f_dc under alpha 0: its WebP encoder drops the RGB of
// transparent texels (6 of the 200), which decode as entry 0. Also read unpacked as a folder.
TEST(SogTest, ReadsSplatTransformBundleAndFolder)
{
    const GaussianCloud src = readGaussians(fixture("random200-sh3.ply"));
    ReadReport report;
    const GaussianCloud dec = readGaussians(fixture("random200-sh3.sog"), {}, &report);
    EXPECT_EQ(report.format, "sog");
    ASSERT_EQ(dec.size(), 200u);
    ASSERT_EQ(dec.shDegree, 3);
    const std::string bytes = fileBytes(fixture("random200-sh3.sog"));
    const sog::ZipIndex zip("random200-sh3.sog", bytes);
    const nlohmann::json meta = nlohmann::json::parse(zip.extract("meta.json", 1 << 20));
    const std::vector<float> scales = meta["scales"]["codebook"], colours = meta["sh0"]["codebook"];
    const std::vector<std::size_t> match = nearestSource(src, dec);
    EXPECT_EQ(std::set<std::size_t>(match.begin(), match.end()).size(), 200u);
    const double d = 2 / (255 * std::sqrt(2.0)), derived = std::sqrt(2 * std::sqrt(3.0) * d + 3 * d * d);
    for (std::size_t t = 0; t < dec.size(); ++t) {
        const std::size_t i = match[t];
        for (int a = 0; a < 3; ++a) {
            const double step = (double(meta["means"]["maxs"][a]) - double(meta["means"]["mins"][a])) / 65535;
            const double x = src.means[3 * i + a];
            ASSERT_NEAR(dec.means[3 * t + a], x, (std::fabs(x) + 1) * std::expm1(step) + 1e-6) << i;
            ASSERT_EQ(dec.logScales[3 * t + a], nearestEntry(scales, src.logScales[3 * i + a])) << i;
            const bool transparent = sigmoidD(src.opacities[i]) * 255 < 1; // truncated to alpha 0
            ASSERT_EQ(dec.shOf(t)[a], transparent ? colours[0] : nearestEntry(colours, src.shOf(i)[a])) << i;
        }
        double q[4], n = 0, dot = 0;
        for (int a = 0; a < 4; ++a) n += double(src.rotations[4 * i + a]) * src.rotations[4 * i + a];
        for (int a = 0; a < 4; ++a) dot += (q[a] = src.rotations[4 * i + a] / std::sqrt(n)) * dec.rotations[4 * t + a];
        for (int a = 0; a < 4; ++a) ASSERT_NEAR((dot < 0 ? -1 : 1) * q[a], dec.rotations[4 * t + a], derived + 1e-6) << i;
        ASSERT_NEAR(sigmoidD(src.opacities[i]), sigmoidD(dec.opacities[t]), 1.0 / 255 + 2e-6) << i;
    }
    TempDir dir; // the same entries as a folder: the same Gaussians
    for (const char* f : {"meta.json", "means_l.webp", "means_u.webp", "quats.webp", "scales.webp", "sh0.webp",
                          "shN_centroids.webp", "shN_labels.webp"})
        writeBytes(dir.file(f), zip.extract(f, 1 << 20));
    const GaussianCloud folder = readGaussians(dir.path().string());
    ASSERT_EQ(folder.size(), dec.size());
    for (std::size_t i = 0; i < dec.size(); ++i) ASSERT_TRUE(folder.sameGaussian(i, dec, i)) << i;
}
