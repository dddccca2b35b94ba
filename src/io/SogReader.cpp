/// SOG reader (PlayCanvas "Spatially Ordered Gaussians", meta.json version 2), as a `.sog` zip
/// bundle or a folder holding meta.json and its images. Decoding follows splat-transform
/// src/lib/readers/read-sog.ts: texel i of every per-Gaussian image is Gaussian i; centres are
/// 16 bits (means_l low byte, means_u high byte) on a grid over sign(x) ln(|x| + 1); quaternions
/// smallest-three in 8 bits with the dropped component in alpha (252 + index); log scales and
/// f_dc index 256-entry codebooks; alpha of sh0 is sigmoid(opacity) in 8 bits; higher SH is a
/// palette (shN_centroids, 64 centroids a row) indexed by 16-bit labels, its values a codebook.
#include <nlohmann/json.hpp>
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "core/Error.h"
#include "io/FormatReaders.h"
#include "io/SogFormat.h"
#include "io/JsonText.h"

namespace splatwarp {

namespace {

using nlohmann::json;
using Loader = std::function<std::string(const std::string& file, std::size_t maxBytes)>;

constexpr std::size_t kMaxMetaBytes = 4u << 20;
// No real scene packs more than 64 Gaussians into a byte of lossless WebP (they take 10-20 bytes
// each); a count beyond that is a decompression bomb of constant images.
constexpr double kMaxGaussiansPerByte = 64;
// Centres beyond 1e15 overflow in use (readGaussians' limits): ln(1e15 + 1).
constexpr double kMaxLogCentre = 34.6;

struct SogMeta {
    std::size_t count = 0;
    double mins[3] = {}, maxs[3] = {};
    std::vector<float> scales, colours, shValues;
    int shDegree = 0;
    std::size_t paletteCount = 0;
    std::string meansL, meansU, quats, scaleFile, sh0, centroids, labels;
    bool antialias = false;
};

const json& field(const std::string& path, const json& obj, const char* key, const std::string& where)
{
    if (!obj.is_object() || !obj.contains(key))
        throw InputError(msg(path, ": meta.json: ", where.empty() ? "" : where + ".", key, " is missing"));
    return obj.at(key);
}

double finiteNumber(const std::string& path, const json& v, const std::string& where)
{
    if (!v.is_number()) throw InputError(msg(path, ": meta.json: ", where, " is not a number (", v.dump(), ")"));
    const double d = v.get<double>();
    if (!std::isfinite(d)) throw InputError(msg(path, ": meta.json: ", where, " is ", d, ", not finite"));
    return d;
}

std::vector<double> numbers(const std::string& path, const json& v, std::size_t n, const std::string& where)
{
    if (!v.is_array() || v.size() != n)
        throw InputError(msg(path, ": meta.json: ", where, " must be an array of ", n, " numbers"));
    std::vector<double> out(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double d = finiteNumber(path, v[i], msg(where, "[", i, "]"));
        if (std::fabs(d) > 1e30) throw InputError(msg(path, ": meta.json: ", where, "[", i, "] is ", d, ", out of range"));
        out[i] = d;
    }
    return out;
}

// The images a section names; plain names only, so a folder read stays inside its folder.
std::vector<float> codebook(const std::string& path, const json& section, const std::string& where)
{
    const std::vector<double> v = numbers(path, field(path, section, "codebook", where), 256, where + ".codebook");
    return std::vector<float>(v.begin(), v.end());
}

std::vector<std::string> files(const std::string& path, const json& section, std::size_t n, const std::string& where)
{
    const json& list = field(path, section, "files", where);
    if (!list.is_array() || list.size() != n)
        throw InputError(msg(path, ": meta.json: ", where, ".files must name ", n, " image", n > 1 ? "s" : ""));
    std::vector<std::string> out;
    for (const json& f : list) {
        const std::string name = f.is_string() ? f.get<std::string>() : std::string();
        if (name.empty() || name == "." || name == ".." || name.find_first_of(std::string("/\\\0", 3)) != std::string::npos)
            throw InputError(msg(path, ": meta.json: ", where, ".files holds ", f.dump(),
                                 ": only plain file names beside meta.json are read"));
        out.push_back(name);
    }
    return out;
}

void parseShN(const std::string& path, const json& meta, SogMeta& m)
{
    if (!meta.contains("shN")) return;
    const json& shN = meta.at("shN");
    const double bands = finiteNumber(path, field(path, shN, "bands", "shN"), "shN.bands");
    if (bands != 0 && bands != 1 && bands != 2 && bands != 3)
        throw InputError(msg(path, ": meta.json: shN.bands is ", bands, " (SH degrees 0-3)"));
    m.shDegree = int(bands);
    if (m.shDegree == 0) return;
    const double count = finiteNumber(path, field(path, shN, "count", "shN"), "shN.count");
    if (count < 1 || count > 65536 || count != std::floor(count))
        throw InputError(msg(path, ": meta.json: shN.count is ", count, " (a palette of 1-65536 centroids)"));
    m.paletteCount = std::size_t(count);
    m.shValues = codebook(path, shN, "shN");
    const std::vector<std::string> f = files(path, shN, 2, "shN");
    m.centroids = f[0];
    m.labels = f[1];
}

SogMeta parseMeta(const std::string& path, const std::string& text)
{
    json meta;
    try {
        meta = parseJson(text);
    } catch (const json::exception& e) {
        throw InputError(msg(path, ": meta.json is not valid JSON (", e.what(), ")"));
    }
    if (!meta.is_object()) throw InputError(msg(path, ": meta.json is not a JSON object"));
    if (!meta.contains("version"))
        throw InputError(msg(path, ": meta.json has no version: SOG version 1 is not supported (re-save with splat-transform)"));
    const double version = finiteNumber(path, meta.at("version"), "version");
    if (version != 2) throw InputError(msg(path, ": SOG version ", version, " is not supported (read: version 2)"));
    SogMeta m;
    const double count = finiteNumber(path, field(path, meta, "count", ""), "count");
    const double maxCount = double(sog::kMaxWebpSide) * sog::kMaxWebpSide;
    if (count < 1 || count > maxCount || count != std::floor(count))
        throw InputError(msg(path, ": meta.json: count is ", count, " (1 to ", maxCount, " Gaussians fit WebP images)"));
    m.count = std::size_t(count);
    const json& means = field(path, meta, "means", "");
    const std::vector<double> lo = numbers(path, field(path, means, "mins", "means"), 3, "means.mins");
    const std::vector<double> hi = numbers(path, field(path, means, "maxs", "means"), 3, "means.maxs");
    for (int a = 0; a < 3; ++a) {
        m.mins[a] = lo[a];
        m.maxs[a] = hi[a];
        if (std::fabs(m.mins[a]) > kMaxLogCentre || std::fabs(m.maxs[a]) > kMaxLogCentre)
            throw InputError(msg(path, ": meta.json: means.mins/maxs[", a, "] = ", lo[a], "/", hi[a],
                                 ": centres beyond 1e15 (log-encoded |value| <= ", kMaxLogCentre, ")"));
    }
    const std::vector<std::string> mf = files(path, means, 2, "means");
    m.meansL = mf[0];
    m.meansU = mf[1];
    m.scales = codebook(path, field(path, meta, "scales", ""), "scales");
    m.scaleFile = files(path, meta.at("scales"), 1, "scales")[0];
    m.quats = files(path, field(path, meta, "quats", ""), 1, "quats")[0];
    m.colours = codebook(path, field(path, meta, "sh0", ""), "sh0");
    m.sh0 = files(path, meta.at("sh0"), 1, "sh0")[0];
    parseShN(path, meta, m);
    m.antialias = meta.contains("antialias") && meta.at("antialias").is_boolean() && meta.at("antialias").get<bool>();
    return m;
}

// Lossless WebP stays under ~4 bytes a texel plus headers; more than this is not a SOG image.
std::size_t maxImageBytes(std::size_t texels) { return 8 * texels + 4096; }

// Texels a per-Gaussian image may have: splat-transform's layout (sides rounded up to multiples
// of 4) and any row-major layout leave at most 4 rows and columns of padding.
bool plausibleTexels(std::size_t count, int w, int h)
{
    const std::size_t texels = std::size_t(w) * std::size_t(h);
    return texels >= count && texels <= count + 4 * (std::size_t(w) + std::size_t(h)) + 16;
}

struct Images {
    std::map<std::string, std::string> bytes;
};

// Every image meta.json names, as compressed bytes, checked before any is decoded: the count
// against the bytes, and each image's declared size against the count.
Images loadImages(const std::string& path, const SogMeta& m, const Loader& load)
{
    Images im;
    std::vector<std::string> perGaussian = {m.meansL, m.meansU, m.quats, m.scaleFile, m.sh0};
    if (m.shDegree > 0) perGaussian.push_back(m.labels);
    const std::size_t maxTexels = m.count + 8 * std::size_t(sog::kMaxWebpSide) + 16;
    double total = 0;
    for (const std::string& f : perGaussian) total += double((im.bytes[f] = load(f, maxImageBytes(maxTexels))).size());
    const int coeffs = shCoeffCount(m.shDegree) - 1;
    const std::size_t rows = (m.paletteCount + sog::kPaletteRow - 1) / sog::kPaletteRow;
    if (m.shDegree > 0)
        total += double((im.bytes[m.centroids] = load(m.centroids, maxImageBytes(rows * sog::kPaletteRow * std::size_t(coeffs)))).size());
    if (double(m.count) > kMaxGaussiansPerByte * total)
        throw InputError(msg(path, ": meta.json: count ", m.count, " is more than ", kMaxGaussiansPerByte,
                             " Gaussians a byte of its ", total, " bytes of images (a decompression bomb?)"));
    const std::pair<int, int> size = sog::webpSize(path + ": " + m.meansL, im.bytes[m.meansL]);
    for (const std::string& f : perGaussian) {
        const std::pair<int, int> s = sog::webpSize(path + ": " + f, im.bytes[f]);
        if (s != size)
            throw InputError(msg(path, ": ", f, " is ", s.first, "x", s.second, ", but ", m.meansL, " is ", size.first,
                                 "x", size.second, " (every per-Gaussian image has one size)"));
    }
    if (!plausibleTexels(m.count, size.first, size.second))
        throw InputError(msg(path, ": images of ", size.first, "x", size.second, " texels do not fit count ", m.count,
                             " (fewer texels than Gaussians, or far more: a decompression bomb?)"));
    if (m.shDegree > 0) {
        const std::pair<int, int> c = sog::webpSize(path + ": " + m.centroids, im.bytes[m.centroids]);
        if (c.first != sog::kPaletteRow * coeffs || c.second < 1 || std::size_t(c.second) > rows)
            throw InputError(msg(path, ": ", m.centroids, " is ", c.first, "x", c.second, "; a palette of ", m.paletteCount,
                                 " centroids of SH degree ", m.shDegree, " is ", sog::kPaletteRow * coeffs, " wide and 1-",
                                 rows, " high"));
    }
    return im;
}

sog::Image decode(const std::string& path, Images& im, const std::string& file)
{
    sog::Image image = sog::decodeWebp(path + ": " + file, im.bytes[file]);
    im.bytes.erase(file); // peak memory: the compressed bytes of the rest and one or two images
    return image;
}

double fromLog(double v) { return v < 0 ? -std::expm1(-v) : std::expm1(v); }

void decodeMeans(const SogMeta& m, const sog::Image& lo, const sog::Image& hi, GaussianCloud& g)
{
    for (std::size_t i = 0; i < m.count; ++i)
        for (int a = 0; a < 3; ++a) {
            const unsigned q = lo.rgba[4 * i + a] | unsigned(hi.rgba[4 * i + a]) << 8;
            g.means[3 * i + a] = float(fromLog(m.mins[a] + (m.maxs[a] - m.mins[a]) * (q / 65535.0)));
        }
}

void decodeQuats(const std::string& path, const SogMeta& m, const sog::Image& img, GaussianCloud& g)
{
    for (std::size_t i = 0; i < m.count; ++i) {
        const std::uint8_t* t = &img.rgba[4 * i];
        if (t[3] < 252)
            throw InputError(msg(path, ": ", m.quats, ": Gaussian ", i, " has alpha ", int(t[3]),
                                 " (the dropped quaternion component, 252-255)"));
        const int largest = t[3] - 252;
        double q[4], sum = 0;
        for (int k = 0, j = 0; k < 4; ++k) {
            if (k == largest) continue;
            q[k] = (t[j++] / 255.0 * 2.0 - 1.0) / std::sqrt(2.0);
            sum += q[k] * q[k];
        }
        q[largest] = std::sqrt(std::max(0.0, 1.0 - sum));
        for (int k = 0; k < 4; ++k) g.rotations[4 * i + std::size_t(k)] = float(q[k]); // w, x, y, z as PLY rot_0..3
    }
}

void decodeScalesAndColours(const SogMeta& m, const sog::Image& scales, const sog::Image& sh0, GaussianCloud& g)
{
    for (std::size_t i = 0; i < m.count; ++i) {
        for (int a = 0; a < 3; ++a) {
            g.logScales[3 * i + a] = m.scales[scales.rgba[4 * i + a]];
            g.shOf(i)[a] = m.colours[sh0.rgba[4 * i + a]];
        }
        g.opacities[i] = logitOfU8Alpha(sh0.rgba[4 * i + 3]);
    }
}

// f_rest is channel-major in SOG (R coefficients, then G, then B), as in graphdeco PLY.
void decodeShN(const std::string& path, const SogMeta& m, const sog::Image& centroids, const sog::Image& labels,
               GaussianCloud& g)
{
    const int coeffs = g.shCoeffs() - 1;
    const std::size_t usable = std::min(m.paletteCount, std::size_t(centroids.height) * sog::kPaletteRow);
    for (std::size_t i = 0; i < m.count; ++i) {
        const std::size_t label = labels.rgba[4 * i] | std::size_t(labels.rgba[4 * i + 1]) << 8;
        if (label >= usable)
            throw InputError(msg(path, ": ", m.labels, ": Gaussian ", i, " names palette entry ", label, ", beyond the ",
                                 usable, " in ", m.centroids));
        const std::size_t row = label / sog::kPaletteRow, col = (label % sog::kPaletteRow) * std::size_t(coeffs);
        for (int j = 0; j < coeffs; ++j) {
            const std::uint8_t* t = &centroids.rgba[4 * (row * std::size_t(centroids.width) + col + std::size_t(j))];
            for (int c = 0; c < 3; ++c) g.shOf(i)[3 * (j + 1) + c] = m.shValues[t[c]];
        }
    }
}

GaussianCloud decodeSog(const std::string& path, const std::string& metaText, const Loader& load, ReadReport& report)
{
    const SogMeta m = parseMeta(path, metaText);
    Images im = loadImages(path, m, load);
    GaussianCloud g;
    g.resize(m.count, m.shDegree);
    {
        const sog::Image lo = decode(path, im, m.meansL), hi = decode(path, im, m.meansU);
        decodeMeans(m, lo, hi, g);
    }
    decodeQuats(path, m, decode(path, im, m.quats), g);
    {
        const sog::Image scales = decode(path, im, m.scaleFile), sh0 = decode(path, im, m.sh0);
        decodeScalesAndColours(m, scales, sh0, g);
    }
    if (m.shDegree > 0) {
        const sog::Image centroids = decode(path, im, m.centroids), labels = decode(path, im, m.labels);
        decodeShN(path, m, centroids, labels, g);
    }
    report.format = "sog";
    if (m.antialias) report.notes.push_back("meta.json: antialias is set (trained with mip-splatting's 2D filter)");
    return g;
}

// At most maxBytes of a regular file; a folder or device is refused without reading, and so is a
// symlink unless it is the meta.json the user named (an image link could leave the folder).
std::string readBounded(const std::string& shown, const std::filesystem::path& file, std::size_t maxBytes,
                        bool followLink = false)
{
    std::error_code ec;
    const std::filesystem::file_status st =
        followLink ? std::filesystem::status(file, ec) : std::filesystem::symlink_status(file, ec);
    if (ec || !std::filesystem::exists(st)) throw IoError(msg(shown, ": cannot open: no such file"));
    if (!std::filesystem::is_regular_file(st))
        throw InputError(msg(shown, ": not a regular file (symlinks and devices beside meta.json are not read)"));
    const std::uintmax_t size = std::filesystem::file_size(file, ec);
    if (ec) throw IoError(msg(shown, ": cannot read its size"));
    if (size > maxBytes) throw InputError(msg(shown, ": ", size, " bytes, more than the ", maxBytes, " this SOG can need"));
    std::ifstream in(file, std::ios::binary);
    std::string data(std::size_t(size), '\0');
    if (!in || !in.read(&data[0], std::streamsize(size))) throw IoError(msg(shown, ": read failed"));
    return data;
}

} // namespace

bool isSogFolderPath(const std::string& path)
{
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) return std::filesystem::exists(std::filesystem::path(path) / "meta.json", ec);
    return std::filesystem::path(path).filename() == "meta.json";
}

GaussianCloud readSog(const std::string& path, const std::string& data, ReadReport& report)
{
    const sog::ZipIndex zip(path, data);
    if (!zip.contains("meta.json")) throw InputError(msg(path, ": a zip without meta.json: not a SOG bundle"));
    const Loader load = [&](const std::string& file, std::size_t maxBytes) { return zip.extract(file, maxBytes); };
    return decodeSog(path, zip.extract("meta.json", kMaxMetaBytes), load, report);
}

GaussianCloud readSogFolder(const std::string& path, ReadReport& report)
{
    std::error_code ec;
    const bool folder = std::filesystem::is_directory(path, ec);
    const std::filesystem::path meta = folder ? std::filesystem::path(path) / "meta.json" : std::filesystem::path(path);
    const std::filesystem::path dir = meta.parent_path().empty() ? "." : meta.parent_path();
    const std::string shown = meta.string();
    const Loader load = [&](const std::string& file, std::size_t maxBytes) {
        return readBounded(msg(shown, ": ", file), dir / file, maxBytes);
    };
    return decodeSog(shown, readBounded(shown, meta, kMaxMetaBytes, true), load, report);
}

} // namespace splatwarp
