// The splat rasteriser on the GPU (see RasterizerCuda.h). Mirrors render/Rasterizer.cpp step by
// step with the shared per-splat maths of render/SplatProjection.h. Notation: N Gaussians,
// T tiles, E tile entries (one per splat and tile it touches), P pixels, K = 3 (degree+1)^2.
//
// This file is compiled with -fmad=false (kernels/CMakeLists.txt): without contracted
// multiply-adds the depths, conics, colours and transmittances are the host's float operations
// bit for bit, so the splats of a pixel come in exactly the CPU's order (the depth is exact) and
// only expf (opacity sigmoid, scales, alpha; <= 2 ulp from glibc) differs.
#include "kernels/RasterizerCuda.h"

#include <cub/cub.cuh>

#include <cstdint>
#include <limits>

#include "kernels/CudaCheck.h"
#include "kernels/CudaLaunch.cuh"
#include "kernels/DeviceBuffer.h"
#include "render/SplatProjection.h"

namespace splatwarp::cuda {
namespace {

// One thread per pixel of a tile; the same count of splats is staged in shared memory per batch.
constexpr int kTilePixels = kSplatTileSize * kSplatTileSize;

/// What compositing needs of a splat: plain data, so a batch can live in shared memory.
struct TileSplat {
    float u, v, conicA, conicB, conicC, opacity, minPower; // ProjectedSplat's fields used by splatAlpha()
    float r, g, b;                                         // view-dependent colour
    int ax0, ay0, ax1, ay1;                                // pixels where alpha can reach the cutoff
};

/// Per Gaussian: project (as the CPU's ProjectOp), store the compositing data, the box of tiles it
/// touches and their count (0 when culled) and its depth bits (positive floats order like them).
__global__ void projectKernel(std::size_t n, const float* means /*[N,3]*/, const float* rotations /*[N,4]*/,
                              const float* logScales /*[N,3]*/, const float* opacities /*[N]*/,
                              const float* sh /*[N,K]*/, int shDegree, PinholeView view,
                              TileSplat* splats /*[N]*/, PixelBox* tileBoxes /*[N]*/,
                              std::uint32_t* depthBits /*[N]*/, std::uint64_t* tileCounts /*[N]*/)
{
    const std::size_t i = globalIndex();
    if (i >= n) return;
    const Vec3f mean(means[3 * i], means[3 * i + 1], means[3 * i + 2]);
    const Quatf rotation{rotations[4 * i], rotations[4 * i + 1], rotations[4 * i + 2], rotations[4 * i + 3]};
    // As GaussianCloud::scale() and alpha(): activated scale and opacity.
    const Vec3f scale(std::exp(logScales[3 * i]), std::exp(logScales[3 * i + 1]), std::exp(logScales[3 * i + 2]));
    ProjectedSplat p;
    PixelBox range, reach;
    if (!projectSplatOnScreen(view, mean, gaussianCovariance(rotation, scale), sigmoid(opacities[i]), p, range,
                              reach)) {
        tileCounts[i] = 0;
        return;
    }
    const Vec3f colour = splatColour(view, shDegree, sh + i * std::size_t(3 * shCoeffCount(shDegree)), mean);
    splats[i] = TileSplat{p.u,    p.v,      p.conicA, p.conicB, p.conicC, p.opacity, p.minPower, colour.x,
                          colour.y, colour.z, reach.x0, reach.y0, reach.x1, reach.y1};
    PixelBox tiles;
    tiles.x0 = range.x0 / kSplatTileSize;
    tiles.y0 = range.y0 / kSplatTileSize;
    tiles.x1 = range.x1 / kSplatTileSize;
    tiles.y1 = range.y1 / kSplatTileSize;
    tileBoxes[i] = tiles;
    tileCounts[i] = std::uint64_t(tiles.x1 - tiles.x0 + 1) * std::uint64_t(tiles.y1 - tiles.y0 + 1);
    depthBits[i] = __float_as_uint(p.depth);
}

/// Per Gaussian: one entry per touched tile, key = tile << 32 | depth bits, value = Gaussian index.
/// Entries are written in Gaussian order, so the stable sort breaks depth ties by index.
__global__ void tileEntriesKernel(std::size_t n, const std::uint64_t* tileCounts /*[N]*/,
                                  const std::uint64_t* tileEnds /*[N] inclusive prefix sum of tileCounts*/,
                                  const PixelBox* tileBoxes /*[N]*/, const std::uint32_t* depthBits /*[N]*/, int tilesX,
                                  std::uint64_t* keys /*[E]*/, std::uint32_t* values /*[E]*/)
{
    const std::size_t i = globalIndex();
    if (i >= n || tileCounts[i] == 0) return;
    std::uint64_t e = tileEnds[i] - tileCounts[i];
    const PixelBox t = tileBoxes[i];
    for (int ty = t.y0; ty <= t.y1; ++ty)
        for (int tx = t.x0; tx <= t.x1; ++tx, ++e) {
            keys[e] = (std::uint64_t(std::uint32_t(ty * tilesX + tx)) << 32) | depthBits[i];
            values[e] = std::uint32_t(i);
        }
}

/// Per sorted entry: the first and one-past-last entry of each tile (tiles without entries keep 0, 0).
__global__ void tileRangesKernel(std::size_t entries, const std::uint64_t* keys /*[E] sorted*/,
                                 std::uint32_t* tileStart /*[T]*/, std::uint32_t* tileEnd /*[T]*/)
{
    const std::size_t e = globalIndex();
    if (e >= entries) return;
    const std::uint64_t tile = keys[e] >> 32;
    if (e == 0 || (keys[e - 1] >> 32) != tile) tileStart[tile] = std::uint32_t(e);
    if (e + 1 == entries || (keys[e + 1] >> 32) != tile) tileEnd[tile] = std::uint32_t(e + 1);
}

/// One block per tile, one thread per pixel: composite the tile's splats front to back in
/// batches staged in shared memory, as the CPU's CompositeOp does per pixel (same skips, same
/// early termination), then write RGB = colour + T background, A = 1 - T.
__global__ void compositeKernel(const TileSplat* splats /*[N]*/, const std::uint32_t* order /*[E] sorted values*/,
                                const std::uint32_t* tileStart /*[T]*/, const std::uint32_t* tileEnd /*[T]*/,
                                int width, int height, Vec3f background, float* image /*[P,4]*/)
{
    __shared__ TileSplat batch[kTilePixels];
    const std::size_t tile = std::size_t(blockIdx.y) * gridDim.x + blockIdx.x;
    const int x = int(blockIdx.x) * kSplatTileSize + int(threadIdx.x);
    const int y = int(blockIdx.y) * kSplatTileSize + int(threadIdx.y);
    const int lane = int(threadIdx.y) * kSplatTileSize + int(threadIdx.x);
    const bool inside = x < width && y < height;
    const float px = float(x) + 0.5f, py = float(y) + 0.5f;
    bool done = !inside;
    float transmittance = 1.0f;
    Vec3f colour(0.0f, 0.0f, 0.0f);
    const std::uint32_t begin = tileStart[tile], end = tileEnd[tile];
    for (std::uint64_t base = begin; base < end; base += kTilePixels) { // 64-bit: no wrap near 2^32 entries
        // Also the barrier before the batch is overwritten. The whole block stops once every pixel
        // is done (uniform decision, so every thread leaves the loop together).
        if (__syncthreads_count(done) == kTilePixels) break;
        if (base + std::uint64_t(lane) < end) batch[lane] = splats[order[base + std::uint64_t(lane)]];
        __syncthreads();
        const int count = int(end - base < std::uint64_t(kTilePixels) ? end - base : std::uint64_t(kTilePixels));
        for (int k = 0; k < count && !done; ++k) {
            const TileSplat& s = batch[k];
            if (x < s.ax0 || x > s.ax1 || y < s.ay0 || y > s.ay1) continue;
            ProjectedSplat p;
            p.u = s.u;
            p.v = s.v;
            p.conicA = s.conicA;
            p.conicB = s.conicB;
            p.conicC = s.conicC;
            p.opacity = s.opacity;
            p.minPower = s.minPower;
            const float alpha = splatAlpha(p, px, py);
            if (alpha == 0.0f) continue;
            const float next = transmittance * (1.0f - alpha);
            // As the CPU and 3DGS: stop before the splat that would make the pixel (almost) opaque.
            if (next < kSplatMinTransmittance) {
                done = true;
                break;
            }
            colour += Vec3f(s.r, s.g, s.b) * (alpha * transmittance);
            transmittance = next;
        }
    }
    if (!inside) return;
    float* out = image + (std::size_t(y) * std::size_t(width) + std::size_t(x)) * 4;
    for (int c = 0; c < 3; ++c) out[c] = colour[c] + transmittance * background[c];
    out[3] = 1.0f - transmittance;
}

/// The cloud's arrays on the device.
struct DeviceGaussians {
    DeviceBuffer<float> means{"Gaussian means"}, rotations{"Gaussian rotations"}, logScales{"Gaussian scales"},
        opacities{"Gaussian opacities"}, sh{"Gaussian SH coefficients"};
    DeviceGaussians(const GaussianCloud& cloud, cudaStream_t stream)
    {
        means.upload(cloud.means, stream);
        rotations.upload(cloud.rotations, stream);
        logScales.upload(cloud.logScales, stream);
        opacities.upload(cloud.opacities, stream);
        sh.upload(cloud.sh, stream);
    }
};

/// Per Gaussian: its compositing data, box of tiles, depth bits and tile entry count; the
/// inclusive scan of the counts places its entries; `entries` is the total.
struct ProjectedSplats {
    DeviceBuffer<TileSplat> splats;
    DeviceBuffer<PixelBox> tileBoxes;
    DeviceBuffer<std::uint32_t> depthBits;
    // 64-bit counts: CUB scans in the input's type, so 32-bit counts would wrap before the
    // overflow check could see the total.
    DeviceBuffer<std::uint64_t> tileCounts, tileEnds;
    std::uint64_t entries = 0;
    explicit ProjectedSplats(std::size_t n)
        : splats(n, "screen splats"), tileBoxes(n, "splat tile boxes"), depthBits(n, "splat depths"),
          tileCounts(n, "splat tile counts"), tileEnds(n, "splat tile offsets")
    {
    }
};

/// Project every Gaussian and count its tile entries (one synchronising read-back of the total).
void projectSplats(const GaussianCloud& cloud, const DeviceGaussians& g, const PinholeView& view,
                   DeviceBuffer<unsigned char>& temp, ProjectedSplats& out, cudaStream_t stream)
{
    const std::size_t n = cloud.size();
    if (n == 0) return;
    launch("projectKernel", projectKernel, n, stream, n, g.means.data(), g.rotations.data(), g.logScales.data(),
           g.opacities.data(), g.sh.data(), cloud.shDegree, view, out.splats.data(), out.tileBoxes.data(),
           out.depthBits.data(), out.tileCounts.data());
    cubCall(temp, [&](void* t, std::size_t& bytes) {
        return cub::DeviceScan::InclusiveSum(t, bytes, out.tileCounts.data(), out.tileEnds.data(), n, stream);
    });
    SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(&out.entries, out.tileEnds.data() + (n - 1), sizeof(out.entries),
                                         cudaMemcpyDeviceToHost, stream));
    SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(stream));
}

/// The tile entries sorted by (tile, depth) and each tile's [start, end) in them (empty tiles
/// keep [0, 0)).
struct TileLists {
    DeviceBuffer<std::uint32_t> tileStart, tileEnd;
    DeviceBuffer<std::uint64_t> keys, sortedKeys;
    DeviceBuffer<std::uint32_t> values, sortedValues;
    TileLists(std::size_t tiles, std::uint64_t entries, cudaStream_t stream)
        : tileStart(tiles, "tile ranges"), tileEnd(tiles, "tile ranges"), keys(entries, "tile sort keys"),
          sortedKeys(entries, "tile sort keys"), values(entries, "tile sort values"),
          sortedValues(entries, "tile sort values")
    {
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(tileStart.data(), 0, tileStart.bytes(), stream));
        SPLATWARP_CUDA_CHECK(cudaMemsetAsync(tileEnd.data(), 0, tileEnd.bytes(), stream));
    }
};

/// Write every (tile, depth) entry, sort them, mark each tile's range.
void sortTileEntries(const ProjectedSplats& p, std::size_t n, std::size_t tiles, int tilesX,
                     DeviceBuffer<unsigned char>& temp, TileLists& lists, cudaStream_t stream)
{
    if (p.entries == 0) return;
    launch("tileEntriesKernel", tileEntriesKernel, n, stream, n, p.tileCounts.data(), p.tileEnds.data(),
           p.tileBoxes.data(), p.depthBits.data(), tilesX, lists.keys.data(), lists.values.data());
    // Sort only the bits in use: 32 depth bits below the bits of the largest tile index.
    int tileBits = 0;
    while ((std::uint64_t(1) << tileBits) < tiles) ++tileBits;
    const std::uint32_t count = std::uint32_t(p.entries);
    cubCall(temp, [&](void* t, std::size_t& bytes) {
        return cub::DeviceRadixSort::SortPairs(t, bytes, lists.keys.data(), lists.sortedKeys.data(), lists.values.data(),
                                               lists.sortedValues.data(), count, 0, 32 + tileBits, stream);
    });
    launch("tileRangesKernel", tileRangesKernel, std::size_t(p.entries), stream, p.entries, lists.sortedKeys.data(),
           lists.tileStart.data(), lists.tileEnd.data());
}

} // namespace

Image renderGaussiansCuda(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options)
{
    checkRenderInputs(cloud, camera);
    const PinholeView view = pinholeView(camera);
    const std::size_t n = cloud.size();
    if (n > std::numeric_limits<std::uint32_t>::max())
        throw DeviceLimitError(msg("CUDA rasteriser: ", n, " Gaussians exceed its 32-bit splat indices"));
    const int tilesX = (view.width + kSplatTileSize - 1) / kSplatTileSize;
    const int tilesY = (view.height + kSplatTileSize - 1) / kSplatTileSize;
    const std::size_t tiles = std::size_t(tilesX) * std::size_t(tilesY);
    const cudaStream_t stream = nullptr; // the default stream: every step waits for the previous one

    const DeviceGaussians gaussians(cloud, stream);
    ProjectedSplats projected(n);
    DeviceBuffer<unsigned char> temp("CUB temporary storage");
    projectSplats(cloud, gaussians, view, temp, projected, stream);
    if (projected.entries > std::numeric_limits<std::uint32_t>::max())
        throw DeviceLimitError(msg("CUDA rasteriser: ", projected.entries, " splat-tile entries exceed its 32-bit offsets ",
                             "(render at a lower resolution)"));
    TileLists lists(tiles, projected.entries, stream);
    sortTileEntries(projected, n, tiles, tilesX, temp, lists, stream);

    DeviceBuffer<float> pixels(std::size_t(view.width) * std::size_t(view.height) * 4, "the image");
    compositeKernel<<<dim3(unsigned(tilesX), unsigned(tilesY)), dim3(kSplatTileSize, kSplatTileSize), 0, stream>>>(
        projected.splats.data(), lists.sortedValues.data(), lists.tileStart.data(), lists.tileEnd.data(), view.width,
        view.height, options.background, pixels.data());
    SPLATWARP_CUDA_CHECK_LAUNCH("compositeKernel");
    Image image(view.width, view.height, 4);
    pixels.download(image.pixels.data(), image.pixels.size(), stream);
    return image;
}

} // namespace splatwarp::cuda
