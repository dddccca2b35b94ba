/// writeGaussians() by extension, the registry of formats implemented above src/io, and `.splat`
/// writing.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/FormatReaders.h"
#include "io/SogIO.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

std::mutex gFormatsMutex;

std::vector<ModelFormatHooks>& formats()
{
    static std::vector<ModelFormatHooks> list; // function-local: safe from static initialisers
    return list;
}

bool endsWith(const std::string& path, const std::string& tail)
{
    if (path.size() < tail.size()) return false;
    std::string end = path.substr(path.size() - tail.size());
    std::transform(end.begin(), end.end(), end.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return end == tail;
}

std::uint8_t unitToU8(double v) { return std::uint8_t(std::clamp(std::round(v * 255.0), 0.0, 255.0)); }

} // namespace

void registerModelFormat(const ModelFormatHooks& hooks)
{
    std::lock_guard<std::mutex> lock(gFormatsMutex);
    for (const ModelFormatHooks& f : formats())
        if (f.name == hooks.name) return;
    formats().push_back(hooks);
}

std::vector<ModelFormatHooks> registeredModelFormats()
{
    std::lock_guard<std::mutex> lock(gFormatsMutex);
    return formats();
}

std::string outputFormatOf(const std::string& path)
{
    if (endsWith(path, ".compressed.ply")) return "compressed-ply"; // SuperSplat's name for it
    if (endsWith(path, "/meta.json") || path == "meta.json") return "sog"; // the folder form
    for (const char* ext : {"ply", "splat", "spz", "glb", "sog"})
        if (endsWith(path, std::string(".") + ext)) return ext;
    for (const ModelFormatHooks& f : registeredModelFormats())
        if (endsWith(path, f.extension)) return f.name;
    return "";
}

void writeGaussians(const std::string& path, const GaussianCloud& g, const WriteOptions& options)
{
    const std::string format = outputFormatOf(path);
    if (format == "compressed-ply") return writeCompressedPly(path, g);
    if (format == "ply") return writePly(path, g);
    if (format == "splat") return writeSplat(path, g);
    if (format == "spz") return writeSpz(path, g, options.spzVersion);
    if (format == "glb") return writeGlb(path, g);
    if (format == "sog") return writeSog(path, g); // default SogOptions: CmdConvert passes its own
    std::string known = ".ply, .compressed.ply, .splat, .spz, .glb, .sog, meta.json (SOG folder)";
    for (const ModelFormatHooks& f : registeredModelFormats()) {
        if (f.name == format) return f.write(path, g);
        known += ", " + f.extension;
    }
    throw UsageError(msg(path, ": cannot tell the output format from the extension (written: ", known, ")"));
}

// antimatter15 records: float32 centre and linear scales, RGBA u8 (colour 0.5 + C0 f_dc, alpha),
// quaternion w, x, y, z as q/|q| * 128 + 128 in u8.
void writeSplat(const std::string& path, const GaussianCloud& g)
{
    g.checkConsistent();
    checkModelForWriting(path, g);
    std::string out(g.size() * kSplatRecordBytes, '\0');
    for (std::size_t i = 0; i < g.size(); ++i) {
        char* r = &out[i * kSplatRecordBytes];
        float f[6];
        for (int a = 0; a < 3; ++a) {
            f[a] = g.means[3 * i + a];
            f[3 + a] = std::exp(g.logScales[3 * i + a]);
        }
        std::memcpy(r, f, sizeof(f)); // little-endian host (see PlyWriter)
        auto* u = reinterpret_cast<unsigned char*>(r + 24);
        for (int c = 0; c < 3; ++c) u[c] = unitToU8(0.5 + kShC0 * g.shOf(i)[c]);
        u[3] = unitToU8(sigmoid(double(g.opacities[i])));
        const Quatf q = g.rotation(i);
        const double n = std::sqrt(double(q.w) * q.w + double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z);
        const float wxyz[4] = {q.w, q.x, q.y, q.z};
        for (int a = 0; a < 4; ++a)
            u[4 + a] = std::uint8_t(std::clamp(std::round(wxyz[a] / n * 128.0 + 128.0), 0.0, 255.0)); // n >= 1e-12: checked above
        const std::string why = splatRecordImplausibility(reinterpret_cast<const unsigned char*>(r));
        if (!why.empty())
            throw InputError(msg(path, ": cannot write .splat: Gaussian ", i, ": ", why,
                                 " (a .splat reader takes such a record for corrupt data; .ply keeps it)"));
    }
    writeFileAtomic(path, out);
}

} // namespace splatwarp
