/// antimatter15 `.splat` reader: 32-byte records, position f32x3, linear scale f32x3, RGBA u8,
/// quaternion u8x4 (w, x, y, z).
#include <cmath>
#include <cstring>

#include "core/Error.h"
#include "io/FormatReaders.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

float logitOfU8Alpha(std::uint32_t a)
{
    const double alpha = std::min(std::max(double(a) / 255.0, kU8AlphaEps), 1.0 - kU8AlphaEps);
    return float(std::log(alpha / (1.0 - alpha)));
}

GaussianCloud readSplat(const std::string& path, const std::string& data, ReadReport& report)
{
    if (data.size() % kSplatRecordBytes != 0)
        throw InputError(msg(path, ": size ", data.size(), " is not a multiple of ", kSplatRecordBytes,
                             " bytes (.splat records)"));
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
