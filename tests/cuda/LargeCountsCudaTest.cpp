// The GPU scans whose totals can pass 2^32: the rasteriser's tile entries, the box bins' entries
// and Stage II's coverage pairs are counted in 64 bits, so a total past 2^32 is refused cleanly
// (DeviceLimitError naming the count, which --device auto turns into a CPU run) instead of
// wrapping into an out-of-range write. Each test drives
// its count past 2^32 for real on the GPU; memory and time on an H200 are stated per test.
// Tests skip with a message where cudaGetDeviceCount finds none.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

#include "kernels/BoxBinsProbe.h"
#include "CudaTestSupport.h"
#include "kernels/RasterizerCuda.h"
#include "kernels/StageTwoCuda.h"
#include "core/Camera.h"
#include "core/Device.h"
#include "core/Error.h"

using namespace splatwarp;

namespace {

constexpr std::uint64_t kTwo32 = std::uint64_t(1) << 32;

/// n copies of one Gaussian at the origin: unit scale, identity rotation, alpha = sigmoid(4).
GaussianCloud unitGaussians(std::size_t n)
{
    GaussianCloud c;
    c.resize(n, 0);
    std::fill(c.opacities.begin(), c.opacities.end(), 4.0f);
    std::fill(c.sh.begin(), c.sh.end(), 0.5f);
    return c;
}

/// Expects f() to throw DeviceLimitError (not out of memory, not bad input: --device auto must
/// run the job on the CPU) whose message contains `what`.
template <typename F>
void expectRefusal(const F& f, const std::string& what)
{
    try {
        f();
        ADD_FAILURE() << "expected DeviceLimitError containing '" << what << "'";
    } catch (const DeviceMemoryError& e) {
        ADD_FAILURE() << "out of memory instead of the count's limit: " << e.what();
    } catch (const DeviceLimitError& e) {
        std::printf("  refused: %s\n", e.what());
        EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
}

/// The host twin of BoxBinsCuda.cuh's binCoord (same double arithmetic, same clamp).
long long binCoordHost(float v, float inv)
{
    const double c = std::floor(double(v) * double(inv)) + double(1ll << 20);
    return (long long)std::min(std::max(c, 0.0), double((1ll << 21) - 1));
}

} // namespace

// 300 splats each covering all 4096 x 4096 tiles of a 65536 x 65536 image: 300 * 2^24 = 5.03e9
// tile entries. Refused after the projection, before any buffer of the entries or the image is
// allocated (a 32-bit scan would wrap to 7.4e8 and tileEntriesKernel write past its buffers).
// Memory: ~40 KB on the GPU; well under a second.
TEST(LargeCountsCuda, RasteriserRefusesTileEntriesPast2To32)
{
    SPLATWARP_REQUIRE_GPU();
    const GaussianCloud cloud = unitGaussians(300);
    // fov 90 at distance 3: sigma = 1 is ~10900 px, the splat's reach (3.3 sigma) passes every edge.
    const Camera camera = Camera::lookAt(Vec3d(0, 0, -3), Vec3d(0, 0, 0), Vec3d(0, 1, 0), 90.0, 65536, 65536);
    static_assert(300ull * 4096 * 4096 > kTwo32, "the entries must pass 2^32");
    expectRefusal([&] { cuda::renderGaussiansCuda(cloud, camera); }, "splat-tile entries exceed its 32-bit offsets");
}

// 33000 copies of one splat covering all 256 x 256 tiles of a 4096 x 4096 image: 2.16e9 tile
// entries, past 2^31 (no signed 32-bit count may hold them) and below the 2^32 limit, so the render
// must succeed. With sigma 2048 px every pixel has alpha >= 0.36 and is opaque within ~21 copies, so
// the image must equal, bit for bit, that of 64 copies (equal depths: index order, the same first
// splats in every pixel). Memory: ~78 GB on the GPU (keys, values, their sorted copies and CUB's
// alternate buffers: ~36 B per entry; skipped with a message where it does not fit); a few seconds.
TEST(LargeCountsCuda, RasteriserPast2To31EntriesEqualsFewCopies)
{
    SPLATWARP_REQUIRE_GPU();
    GaussianCloud many = unitGaussians(33000), few = unitGaussians(64);
    for (GaussianCloud* c : {&many, &few}) std::fill(c->logScales.begin(), c->logScales.end(), std::log(3.0f));
    const Camera camera = Camera::lookAt(Vec3d(0, 0, -3), Vec3d(0, 0, 0), Vec3d(0, 1, 0), 90.0, 4096, 4096);
    static_assert(33000ull * 256 * 256 > (1ull << 31) && 33000ull * 256 * 256 < kTwo32, "between 2^31 and 2^32");
    const Image a = cuda::renderGaussiansCuda(few, camera);
    Image b;
    try {
        b = cuda::renderGaussiansCuda(many, camera);
    } catch (const DeviceMemoryError& e) {
        GTEST_SKIP() << "needs ~78 GB of GPU memory: " << e.what();
    }
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    std::size_t differ = 0, transparent = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) differ += a.pixels[i] != b.pixels[i];
    for (std::size_t i = 3; i < a.pixels.size(); i += 4) transparent += a.pixels[i] < 0.99f;
    std::printf("  %zu of %zu values differ; %zu pixels with alpha < 0.99\n", differ, a.pixels.size(), transparent);
    EXPECT_EQ(transparent, 0u) << "the premise (every pixel opaque within 64 copies) does not hold";
    EXPECT_EQ(differ, 0u);
}

// Two boxes spanning every cell of the 2^21-per-axis key range (2^63 cells each: their sum is
// 2^64, which wraps to 0 without the per-box cap) among 2.5M point boxes (which make the first
// cell small enough for that). With the cap the cell doubles until the entries fit (~4.6e8), and
// the total must equal the host's sum of the capped per-box counts at the final cell.
// Memory: ~20 GB on the GPU at the final cell (entries, sorted copies, CUB's buffers); the two
// big boxes are filled by one thread each: a few seconds.
TEST(LargeCountsCuda, BoxBinsCapHugeBoxesSoTheTotalNeverWraps)
{
    SPLATWARP_REQUIRE_GPU();
    const std::size_t points = 2500000, huge = 2;
    std::vector<float> lo(3 * (points + huge), 0.0f), hi(3 * (points + huge), 0.0f);
    for (std::size_t k = 0; k < huge; ++k)
        for (int a = 0; a < 3; ++a) {
            lo[3 * k + std::size_t(a)] = -1e30f;
            hi[3 * k + std::size_t(a)] = 1e30f;
        }
    const cuda::BoxBinsProbe p = cuda::probeBoxBins(lo, hi);
    ASSERT_TRUE(p.built);
    std::uint64_t expected = 0;
    for (std::size_t k = 0; k < points + huge; ++k) {
        std::uint64_t c = 1;
        for (int a = 0; a < 3; ++a)
            c *= std::uint64_t(binCoordHost(hi[3 * k + std::size_t(a)], p.inv) - binCoordHost(lo[3 * k + std::size_t(a)], p.inv) + 1);
        expected += std::min<std::uint64_t>(c, std::uint64_t(1) << 40);
    }
    std::printf("  box bins: %llu entries, cell %.3g\n", (unsigned long long)p.entries, 1.0 / double(p.inv));
    EXPECT_EQ(p.entries, expected);
    EXPECT_LE(double(p.entries), 256.0 * double(points + huge)); // BoxBins::kMaxEntriesPerBox per box
    EXPECT_GT(p.entries, points);                                 // the big boxes are in
}

// 3000 moving Gaussians each covering all 128^3 samples: 6.3e9 coverage pairs. Stage II's count
// pass scans them in 64 bits and refuses before allocating the pair lists (a 32-bit total would
// wrap to 2.0e9 and the fill pass write past them).
// Memory: ~60 MB on the GPU; the count pass tests 6.3e9 (sample, box) candidates: about a second.
TEST(LargeCountsCuda, StageTwoRefusesCoveragePairsPast2To32)
{
    SPLATWARP_REQUIRE_GPU();
    constexpr int n = 128;
    const GaussianCloud cloud = unitGaussians(3000);
    SampleSet s;
    s.shDegree = 0;
    s.samplesPerAxis = n;
    s.cellSize = 0.2f;
    s.spacing = s.cellSize / float(n);
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b)
            for (int c = 0; c < n; ++c)
                for (int v : {a, b, c}) s.restPositions.push_back(-0.1f + s.spacing * (float(v) + 0.5f));
    s.warpedPositions = s.restPositions;
    const std::size_t m = s.restPositions.size() / 3;
    s.targetF.assign(3 * m, 0.0f);
    s.targetO.assign(m, 1.0f);
    s.sampleCell.assign(m, 0);
    s.cellGradient = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    s.cellSkip = {0};
    static_assert(3000ull * n * n * n > kTwo32, "the pairs must pass 2^32");
    const std::vector<std::uint8_t> moving(cloud.size(), 1);
    const std::vector<std::int32_t> cells(cloud.size(), 0);
    expectRefusal([&] { cuda::probeStageTwoCuda(cloud, s, moving, cells, StageTwoOptions{}); },
                  "pairs; too many for 32-bit indices"); // the coverage count, not the bins
}
