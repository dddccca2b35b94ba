#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/GaussianIO.h"

namespace splatwarp {

std::vector<std::string> graphdecoPropertyNames(int shDegree)
{
    std::vector<std::string> names = {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"};
    const int rest = 3 * (shCoeffCount(shDegree) - 1);
    for (int i = 0; i < rest; ++i) names.push_back("f_rest_" + std::to_string(i));
    names.push_back("opacity");
    for (int i = 0; i < 3; ++i) names.push_back("scale_" + std::to_string(i));
    for (int i = 0; i < 4; ++i) names.push_back("rot_" + std::to_string(i));
    return names;
}

void writePly(const std::string& path, const GaussianCloud& g)
{
    g.checkConsistent();
    checkModelForWriting(path, g);
    const std::size_t n = g.size();
    const int k = g.shCoeffs();
    const std::vector<std::string> names = graphdecoPropertyNames(g.shDegree);

    // One record per Gaussian in graphdeco order; f_rest is channel-major (R block, G, B).
    std::vector<float> rec(names.size());
    std::vector<float> body(n * rec.size());
    for (std::size_t i = 0; i < n; ++i) {
        float* r = body.data() + i * rec.size();
        std::size_t o = 0;
        for (int a = 0; a < 3; ++a) r[o++] = g.means[3 * i + a];
        for (int a = 0; a < 3; ++a) r[o++] = 0.0f;
        const float* sh = g.shOf(i);
        for (int c = 0; c < 3; ++c) r[o++] = sh[c];
        for (int c = 0; c < 3; ++c)
            for (int j = 1; j < k; ++j) r[o++] = sh[3 * j + c];
        r[o++] = g.opacities[i];
        for (int a = 0; a < 3; ++a) r[o++] = g.logScales[3 * i + a];
        for (int a = 0; a < 4; ++a) r[o++] = g.rotations[4 * i + a];
    }

    std::string header = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(n) + "\n";
    for (const std::string& name : names) header += "property float " + name + "\n";
    header += "end_header\n";

    AtomicFile file(path);
    {
        std::ofstream out(file.tempPath(), std::ios::binary);
        if (!out) throw IoError(msg(path, ": cannot open for writing: ", std::strerror(errno)));
        out.write(header.data(), std::streamsize(header.size()));
        // Little-endian host assumed (x86-64, aarch64); checked at compile time below.
        static_assert(sizeof(float) == 4, "float32 expected");
        out.write(reinterpret_cast<const char*>(body.data()), std::streamsize(body.size() * sizeof(float)));
        out.close();
        if (!out) throw IoError(msg(path, ": write failed (disk full or file size limit?)"));
    }
    file.commit();
}

} // namespace splatwarp
