/// readGaussians(): read the file, detect the format from its content, apply the NaN/Inf policy.
#include <cmath>
#include <limits>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/FormatReaders.h"
#include "io/SogFormat.h"

namespace splatwarp {

namespace {

// Values that are finite on disk but overflow in use: exp(log-scale) squared into a float
// covariance, squared distances of centres, |q|^2 of a quaternion.
constexpr float kMaxAbsLogScale = 40.0f; // exp(40)^2 = 5.5e34 < FLT_MAX
constexpr float kMaxAbsCentre = 1e15f;   // (1e15)^2 = 1e30 < FLT_MAX
constexpr double kMinQuatNorm = 1e-12, kMaxQuatNorm = 1e18;

// Number of unusable values of Gaussian i (NaN/Inf, or out of the limits above); `first`
// receives the name and value of the first one.
int countInvalid(const GaussianCloud& g, std::size_t i, std::string* first)
{
    int bad = 0;
    const auto check = [&](float v, float limit, const auto& name) {
        if (std::isfinite(v) && std::fabs(v) <= limit) return;
        if (bad++ == 0 && first)
            *first = std::isfinite(v) ? msg(name(), "' is ", v, " (|value| must be <= ", limit, " to stay finite in use)")
                                      : msg(name(), "' is ", v);
    };
    const float inf = std::numeric_limits<float>::infinity();
    static const char* const xyz[] = {"x", "y", "z"};
    for (int a = 0; a < 3; ++a) check(g.means[3 * i + a], kMaxAbsCentre, [&] { return std::string(xyz[a]); });
    const float* sh = g.shOf(i);
    for (int j = 0; j < g.shCoeffs(); ++j)
        for (int c = 0; c < 3; ++c) check(sh[3 * j + c], inf, [&] { return shPropertyName(g.shDegree, j, c); });
    check(g.opacities[i], inf, [] { return std::string("opacity"); });
    for (int a = 0; a < 3; ++a) check(g.logScales[3 * i + a], kMaxAbsLogScale, [&] { return "scale_" + std::to_string(a); });
    double q2 = 0.0;
    for (int a = 0; a < 4; ++a) {
        check(g.rotations[4 * i + a], inf, [&] { return "rot_" + std::to_string(a); });
        q2 += double(g.rotations[4 * i + a]) * g.rotations[4 * i + a];
    }
    if (std::isfinite(q2) && !(std::sqrt(q2) >= kMinQuatNorm && std::sqrt(q2) <= kMaxQuatNorm) && bad++ == 0 && first)
        *first = msg("rot_0..3' have norm ", std::sqrt(q2), " (no defined rotation; must be in [", kMinQuatNorm, ", ",
                     kMaxQuatNorm, "])");
    return bad;
}

} // namespace

void checkModelForWriting(const std::string& path, const GaussianCloud& g)
{
    if (g.empty()) throw InputError(msg(path, ": refusing to write a model without Gaussians (every reader, ours too, would refuse the file)"));
    for (std::size_t i = 0; i < g.size(); ++i) {
        std::string first;
        if (countInvalid(g, i, &first) > 0)
            throw InputError(msg(path, ": refusing to write Gaussian ", i, ": property '", first,
                                 " (every reader, ours too, would refuse the file)"));
    }
}

namespace {

void applyInvalidPolicy(const std::string& path, GaussianCloud& g, const ReadOptions& options, ReadReport& report)
{
    std::size_t firstBad = g.size();
    std::string firstName;
    std::vector<char> bad(g.size(), 0);
    for (std::size_t i = 0; i < g.size(); ++i) {
        std::string name;
        const int n = countInvalid(g, i, firstBad == g.size() ? &name : nullptr);
        if (n == 0) continue;
        if (firstBad == g.size()) {
            firstBad = i;
            firstName = name;
        }
        bad[i] = 1;
        report.invalidValues += std::size_t(n);
        ++report.invalidGaussians;
    }
    if (report.invalidGaussians == 0 || options.keepInvalid) return;
    if (!options.dropInvalid)
        throw InputError(msg(path, ": Gaussian ", firstBad, ": property '", firstName, " (", report.invalidGaussians,
                             " Gaussians hold ", report.invalidValues,
                             " NaN/Inf or unusable values; --drop-invalid (Python: drop_invalid=True) drops them)"));
    GaussianCloud kept;
    kept.shDegree = g.shDegree;
    for (std::size_t i = 0; i < g.size(); ++i)
        if (!bad[i]) kept.append(g, i);
    report.dropped = report.invalidGaussians;
    report.notes.push_back(msg("dropped ", report.dropped, " Gaussians with NaN/Inf or unusable values"));
    g = std::move(kept);
}

// OpenVDB files start with the 64-bit magic 0x56444220 ("VDB " read as little-endian).
bool hasOpenVdbMagic(const std::string& data) { return data.compare(0, 8, std::string(" BDV\0\0\0\0", 8)) == 0; }

} // namespace

void applyReadRules(const std::string& name, GaussianCloud& cloud, const ReadOptions& options, ReadReport* report)
{
    ReadReport local;
    applyInvalidPolicy(name, cloud, options, local);
    if (report) *report = std::move(local);
}

std::string shPropertyName(int shDegree, int j, int c)
{
    if (j == 0) return "f_dc_" + std::to_string(c);
    return "f_rest_" + std::to_string(c * (shCoeffCount(shDegree) - 1) + j - 1);
}

GaussianCloud readGaussiansFromBytes(const std::string& name, const std::string& data, const ReadOptions& options,
                                     ReadReport* report)
{
    if (data.empty()) throw InputError(msg(name, ": empty file"));
    ReadReport local;
    GaussianCloud g;
    // A .splat may start with another format's magic by chance (gzip: 1 in 65536); its records decide.
    const auto notSplat = [&] { return !(data.size() % kSplatRecordBytes == 0 && splatImplausibility(data).empty()); };
    const ModelFormatHooks* other = nullptr;
    const std::vector<ModelFormatHooks> registered = registeredModelFormats();
    for (const ModelFormatHooks& f : registered)
        if (!other && f.detect(data)) other = &f;
    if (hasPlyMagic(data)) {
        const PlyHeader header = parsePlyHeader(name, data);
        const PlyBody body(name, data, header);
        g = isCompressedPly(header) ? readCompressedPly(name, header, body, local)
                                    : readGraphdecoPly(name, header, body, local);
    } else if (sog::hasZipMagic(data) && notSplat()) {
        g = readSog(name, data, local);
    } else if (hasGlbMagic(data) && notSplat()) {
        g = readGlb(name, data, local);
    } else if (other && notSplat()) {
        g = other->read(name, data, local);
    } else if (hasSpzMagic(data) && notSplat()) {
        g = readSpz(name, data, local);
    } else if (hasOpenVdbMagic(data) && notSplat()) {
        throw InputError(msg(name, ": an OpenVDB file; point grids are read by programs linked with splatwarp_vdb "
                                   "(registerVdbPointFormat() in vdb/VdbPoints.h), volumes by 'from-vdb'"));
    } else {
        g = readSplat(name, data, local);
    }
    applyInvalidPolicy(name, g, options, local);
    if (report) *report = std::move(local);
    return g;
}

GaussianCloud readGaussians(const std::string& path, const ReadOptions& options, ReadReport* report)
{
    if (isSogFolderPath(path)) { // its images lie beside it: read by path, not as bytes
        ReadReport local;
        GaussianCloud g = readSogFolder(path, local);
        applyInvalidPolicy(path, g, options, local);
        if (report) *report = std::move(local);
        return g;
    }
    return readGaussiansFromBytes(path, readWholeFile(path), options, report);
}

} // namespace splatwarp
