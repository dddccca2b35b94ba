/// antimatter15 `.splat` reader: 32-byte records, position f32x3, linear scale f32x3, RGBA u8,
/// quaternion u8x4 (w, x, y, z). The format has no magic, so readSplat() first checks that the
/// records look like Gaussians (splatPlausibility()); text, a cut .vdb or random bytes do not.
#include <cmath>
#include <cstring>

#include "core/Error.h"
#include "io/FormatReaders.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

// Bounds of a plausible record. Positions and scales beyond 1e7 have float32 steps of 1 or more:
// no trained model uses them, while text read as floats gives 1e19..1e38 or 1e-19..1e-10.
constexpr double kMaxPlausibleCoordinate = 1e7;
// Writers store q / |q| * 128 + 128 rounded and clipped to u8, so the stored norm is within
// 2 * sqrt(4) / 256 ~ 0.016 of 1 (lastchance.splat: 0.992..1.006); 0.05 leaves room.
constexpr double kQuaternionNormTolerance = 0.05;
// Share of the judged records that must be plausible: a few degenerate records (zero quaternion
// written as bytes 0) must not make a real file unreadable; text and binary fail nearly all.
constexpr double kMinPlausibleShare = 0.9;

// Whether record r is a plausible Gaussian; `why` (when given) receives the reason if not.
// Records holding NaN/Inf are left to the invalid-value policy (`judged` false).
bool plausibleRecord(const unsigned char* r, bool& judged, std::string* why)
{
    float f[6];
    std::memcpy(f, r, sizeof(f)); // little-endian float32, as the host (see PlyWriter)
    judged = true;
    for (float v : f) judged = judged && std::isfinite(v);
    if (!judged) return false;
    for (int a = 0; a < 3; ++a)
        if (std::fabs(f[a]) > kMaxPlausibleCoordinate) {
            if (why) *why = msg("position ", f[a], " beyond +-1e7");
            return false;
        }
    for (int a = 3; a < 6; ++a)
        if (f[a] < 0 || f[a] > kMaxPlausibleCoordinate) {
            if (why) *why = msg("scale ", f[a], " not in [0, 1e7]");
            return false;
        }
    double norm2 = 0;
    for (int a = 0; a < 4; ++a) norm2 += std::pow((double(r[28 + a]) - 128.0) / 128.0, 2);
    if (std::fabs(std::sqrt(norm2) - 1.0) <= kQuaternionNormTolerance) return true;
    if (why) *why = msg("quaternion bytes of norm ", std::sqrt(norm2), ", not 1");
    return false;
}

} // namespace

std::string splatRecordImplausibility(const unsigned char* record)
{
    bool judged = false;
    std::string why;
    if (plausibleRecord(record, judged, &why)) return {};
    return judged ? why : "position or scale not finite";
}

std::string splatImplausibility(const std::string& data)
{
    const std::size_t n = data.size() / kSplatRecordBytes;
    std::size_t judged = 0, plausible = 0, firstBad = n;
    std::string firstWhy;
    for (std::size_t i = 0; i < n; ++i) {
        bool isJudged = false;
        const auto* r = reinterpret_cast<const unsigned char*>(data.data()) + i * kSplatRecordBytes;
        const bool ok = plausibleRecord(r, isJudged, firstBad == n ? &firstWhy : nullptr);
        judged += isJudged;
        plausible += ok;
        if (isJudged && !ok && firstBad == n) firstBad = i;
    }
    if (judged > 0 && double(plausible) >= kMinPlausibleShare * double(judged)) return {};
    if (judged == 0) return "no record has finite values";
    return msg(plausible, " of ", judged, " records look like Gaussians (record ", firstBad, ": ", firstWhy, ")");
}

float logitOfU8Alpha(std::uint32_t a)
{
    const double alpha = std::min(std::max(double(a) / 255.0, kU8AlphaEps), 1.0 - kU8AlphaEps);
    return float(std::log(alpha / (1.0 - alpha)));
}

GaussianCloud readSplat(const std::string& path, const std::string& data, ReadReport& report)
{
    if (data.size() % kSplatRecordBytes != 0 || data.empty())
        throw InputError(msg(path, ": not a Gaussian file: no 'ply' or .spz magic, and its size (", data.size(),
                             " bytes) is not a positive multiple of ", kSplatRecordBytes, " as a .splat would be"));
    const std::string why = splatImplausibility(data);
    if (!why.empty())
        throw InputError(msg(path, ": not a Gaussian file: no 'ply' or .spz magic, and its ", data.size(),
                             " bytes do not read as .splat records: ", why));
    const std::size_t n = data.size() / kSplatRecordBytes;
    GaussianCloud g;
    g.resize(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        const char* r = data.data() + i * kSplatRecordBytes;
        float f[6]; // little-endian float32, as the host (see PlyWriter)
        std::memcpy(f, r, sizeof(f));
        const auto* u = reinterpret_cast<const unsigned char*>(r + 24);
        for (int a = 0; a < 3; ++a) {
            g.means[3 * i + a] = f[a];
            g.logScales[3 * i + a] = float(std::log(double(f[3 + a])));
            g.sh[3 * i + a] = float((u[a] / 255.0 - 0.5) / kShC0);
        }
        g.opacities[i] = logitOfU8Alpha(u[3]);
        // Stored as is (not normalised): the cloud keeps raw quaternions.
        for (int a = 0; a < 4; ++a) g.rotations[4 * i + a] = float((double(u[4 + a]) - 128.0) / 128.0);
    }
    report.format = "splat";
    return g;
}

} // namespace splatwarp
