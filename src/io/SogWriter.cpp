/// SOG writer (meta.json version 2 + lossless WebP), laid out as splat-transform
/// src/lib/writers/write-sog.ts writes it: Gaussians in Morton order of their centres, one texel
/// each; centres as sign(x) ln(|x| + 1) on a 16-bit grid between the per-axis min and max;
/// quaternions smallest-three; log scales and f_dc through 256-entry codebooks; sigmoid(opacity)
/// in sh0's alpha; higher SH as a k-means palette. We round where splat-transform truncates (half
/// the error, decoded the same way).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "io/FormatReaders.h"
#include "io/SogFormat.h"
#include "io/SogIO.h"

namespace splatwarp {

namespace {

using nlohmann::json;

std::uint8_t roundU8(double v) { return std::uint8_t(std::clamp(std::round(v), 0.0, 255.0)); }

double toLog(double x) { return x < 0 ? -std::log1p(-x) : std::log1p(x); }

sog::Image blank(std::pair<int, int> size, int width = 0, int height = 0)
{
    sog::Image im;
    im.width = width ? width : size.first;
    im.height = height ? height : size.second;
    im.rgba.assign(std::size_t(im.width) * std::size_t(im.height) * 4, 0);
    return im;
}

json packMeans(const GaussianCloud& g, const std::vector<std::size_t>& order, sog::Image& lo, sog::Image& hi)
{
    double mins[3], maxs[3];
    for (int a = 0; a < 3; ++a) {
        mins[a] = maxs[a] = toLog(g.means[std::size_t(a)]);
        for (std::size_t i = 0; i < g.size(); ++i) {
            mins[a] = std::min(mins[a], toLog(g.means[3 * i + std::size_t(a)]));
            maxs[a] = std::max(maxs[a], toLog(g.means[3 * i + std::size_t(a)]));
        }
    }
    for (std::size_t t = 0; t < order.size(); ++t) {
        for (int a = 0; a < 3; ++a) {
            const double range = maxs[a] - mins[a];
            const double v = range > 0 ? (toLog(g.means[3 * order[t] + std::size_t(a)]) - mins[a]) / range : 0.0;
            const auto q = std::uint32_t(std::clamp(std::round(v * 65535.0), 0.0, 65535.0));
            lo.rgba[4 * t + std::size_t(a)] = std::uint8_t(q & 0xff);
            hi.rgba[4 * t + std::size_t(a)] = std::uint8_t(q >> 8);
        }
        lo.rgba[4 * t + 3] = hi.rgba[4 * t + 3] = 255;
    }
    return {{"mins", {mins[0], mins[1], mins[2]}}, {"maxs", {maxs[0], maxs[1], maxs[2]}},
            {"files", {"means_l.webp", "means_u.webp"}}};
}

// Smallest three: the largest |component| is dropped (its index in alpha as 252 + index) and made
// positive; the others, at most sqrt(1/2) in size, are stored as (q sqrt 2 + 1) / 2 in 8 bits.
void packQuats(const GaussianCloud& g, const std::vector<std::size_t>& order, sog::Image& im)
{
    for (std::size_t t = 0; t < order.size(); ++t) {
        double q[4], n = 0;
        for (int k = 0; k < 4; ++k) n += double(g.rotations[4 * order[t] + std::size_t(k)]) * g.rotations[4 * order[t] + std::size_t(k)];
        for (int k = 0; k < 4; ++k) q[k] = g.rotations[4 * order[t] + std::size_t(k)] / std::sqrt(n);
        int largest = 0;
        for (int k = 1; k < 4; ++k)
            if (std::fabs(q[k]) > std::fabs(q[largest])) largest = k;
        const double s = (q[largest] < 0 ? -1.0 : 1.0) * std::sqrt(2.0);
        for (int k = 0, j = 0; k < 4; ++k)
            if (k != largest) im.rgba[4 * t + std::size_t(j++)] = roundU8(255.0 * (q[k] * s * 0.5 + 0.5));
        im.rgba[4 * t + 3] = std::uint8_t(252 + largest);
    }
}

// Three values a Gaussian (log scales or f_dc) through one codebook into RGB; alpha from `alpha`.
template <typename Value, typename Alpha>
json packCodebook(const std::vector<std::size_t>& order, const Value& value, const Alpha& alpha, sog::Image& im,
                  const char* file)
{
    std::vector<float> values(3 * order.size());
    for (std::size_t t = 0; t < order.size(); ++t)
        for (int a = 0; a < 3; ++a) values[3 * t + std::size_t(a)] = value(order[t], a);
    const sog::Codebook book = sog::quantize256(values);
    for (std::size_t t = 0; t < order.size(); ++t) {
        for (int a = 0; a < 3; ++a) im.rgba[4 * t + std::size_t(a)] = book.labels[3 * t + std::size_t(a)];
        im.rgba[4 * t + 3] = alpha(order[t]);
    }
    return {{"codebook", book.entries}, {"files", {file}}};
}

// Higher SH: k-means over each Gaussian's f_rest (channel-major, as SOG orders it), the centroids'
// values through one codebook; centroid c takes texels (c % 64) * coeffs + j of row c / 64.
json packShN(const GaussianCloud& g, const std::vector<std::size_t>& order, const SogOptions& options,
             sog::Image& centroids, sog::Image& labels)
{
    const int coeffs = g.shCoeffs() - 1, dims = 3 * coeffs;
    std::vector<float> points(order.size() * std::size_t(dims));
    for (std::size_t t = 0; t < order.size(); ++t)
        for (int c = 0; c < 3; ++c)
            for (int j = 0; j < coeffs; ++j)
                points[t * std::size_t(dims) + std::size_t(c * coeffs + j)] = g.shOf(order[t])[3 * (j + 1) + c];
    const std::size_t entries = sog::paletteSize(order.size(), options.maxPalette);
    if (order.size() >= 100000) // seconds to minutes
        progress(msg("SOG: clustering the SH of ", order.size(), " Gaussians into ", entries, " palette entries (",
                     options.iterations, " k-means rounds)"));
    const sog::Palette p = sog::kmeans(points, order.size(), dims, entries, options.iterations, options.seed);
    const sog::Codebook book = sog::quantize256(p.centroids);
    const int rows = int((p.count + sog::kPaletteRow - 1) / sog::kPaletteRow);
    centroids = blank({}, sog::kPaletteRow * coeffs, rows);
    for (std::size_t k = 0; k < p.count; ++k)
        for (int j = 0; j < coeffs; ++j) {
            const std::size_t texel = (k / sog::kPaletteRow) * std::size_t(centroids.width) +
                                      (k % sog::kPaletteRow) * std::size_t(coeffs) + std::size_t(j);
            for (int c = 0; c < 3; ++c)
                centroids.rgba[4 * texel + std::size_t(c)] = book.labels[k * std::size_t(dims) + std::size_t(c * coeffs + j)];
            centroids.rgba[4 * texel + 3] = 255;
        }
    for (std::size_t t = 0; t < order.size(); ++t) {
        labels.rgba[4 * t] = std::uint8_t(p.labels[t] & 0xff);
        labels.rgba[4 * t + 1] = std::uint8_t(p.labels[t] >> 8);
        labels.rgba[4 * t + 3] = 255;
    }
    return {{"count", p.count}, {"bands", g.shDegree}, {"codebook", book.entries},
            {"files", {"shN_centroids.webp", "shN_labels.webp"}}};
}

} // namespace

std::vector<std::pair<std::string, std::string>> encodeSogFiles(const std::string& path, const GaussianCloud& g,
                                                                 const SogOptions& options)
{
    g.checkConsistent();
    checkModelForWriting(path, g);
    const std::pair<int, int> size = sog::imageSize(g.size());
    if (size.first > sog::kMaxWebpSide || size.second > sog::kMaxWebpSide)
        throw InputError(msg(path, ": ", g.size(), " Gaussians need ", size.first, "x", size.second,
                             " texels, beyond WebP's 16383x16383"));
    const std::vector<std::size_t> order = compressedPlyOrder(g);
    sog::Image lo = blank(size), hi = blank(size), quats = blank(size), scales = blank(size), sh0 = blank(size);
    json meta = {{"version", 2}, {"asset", {{"generator", "splatwarp"}}}, {"count", g.size()}};
    meta["means"] = packMeans(g, order, lo, hi);
    packQuats(g, order, quats);
    meta["scales"] = packCodebook(order, [&](std::size_t i, int a) { return g.logScales[3 * i + std::size_t(a)]; },
                                  [](std::size_t) { return std::uint8_t(255); }, scales, "scales.webp");
    meta["quats"] = {{"files", {"quats.webp"}}};
    meta["sh0"] = packCodebook(order, [&](std::size_t i, int a) { return g.shOf(i)[a]; },
                               [&](std::size_t i) { return roundU8(255.0 * sigmoid(double(g.opacities[i]))); }, sh0, "sh0.webp");
    std::vector<std::pair<std::string, std::string>> files = {
        {"means_l.webp", sog::encodeWebp(lo)}, {"means_u.webp", sog::encodeWebp(hi)}, {"scales.webp", sog::encodeWebp(scales)},
        {"quats.webp", sog::encodeWebp(quats)}, {"sh0.webp", sog::encodeWebp(sh0)}};
    if (g.shDegree > 0) {
        sog::Image centroids, labels = blank(size);
        meta["shN"] = packShN(g, order, options, centroids, labels);
        files.emplace_back("shN_centroids.webp", sog::encodeWebp(centroids));
        files.emplace_back("shN_labels.webp", sog::encodeWebp(labels));
    }
    files.emplace_back("meta.json", meta.dump());
    return files;
}

std::string encodeSog(const std::string& path, const GaussianCloud& g, const SogOptions& options)
{
    return sog::storedZip(encodeSogFiles(path, g, options));
}

void writeSog(const std::string& path, const GaussianCloud& g, const SogOptions& options)
{
    const std::filesystem::path meta(path);
    if (meta.filename() != "meta.json") return writeFileAtomic(path, encodeSog(path, g, options));
    const std::vector<std::pair<std::string, std::string>> files = encodeSogFiles(path, g, options);
    const std::filesystem::path dir = meta.parent_path();
    if (!dir.empty() && OutputSet::active()) OutputSet::active()->createDirectory(dir.string());
    if (g.shDegree == 0 && OutputSet::active()) // an earlier export's SH images would sit beside a meta.json without them
        for (const char* stale : {"shN_centroids.webp", "shN_labels.webp"}) OutputSet::active()->removeOnCommit((dir / stale).string());
    for (const auto& [name, bytes] : files) // meta.json last: a reader never sees it before its images
        writeFileAtomic(name == "meta.json" ? path : (dir / name).string(), bytes);
}

} // namespace splatwarp
