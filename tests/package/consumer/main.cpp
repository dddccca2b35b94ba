// Writes a three-Gaussian model in every format through the installed library and reads each
// back; exit 0 when every count and the SH degree survive.
#include <cstdio>
#include <string>

#include "vdb/VdbPoints.h"
#include "io/GaussianIO.h"
#include "splatwarp/Version.h"

int main(int argc, char** argv)
{
    if (argc < 2) return 2;
    splatwarp::registerVdbPointFormat();
    splatwarp::GaussianCloud g;
    g.resize(3, 1);
    for (int i = 0; i < 3; ++i) g.means[3 * i] = float(i);
    int bad = 0;
    for (const char* ext : {".ply", ".spz", ".glb", ".splat", ".vdb"}) {
        const std::string path = std::string(argv[1]) + "/model" + ext;
        splatwarp::writeGaussians(path, g);
        splatwarp::ReadReport report;
        const splatwarp::GaussianCloud back = splatwarp::readGaussians(path, {}, &report);
        const bool ok = back.size() == 3 && back.shDegree == (std::string(ext) == ".splat" ? 0 : 1);
        std::printf("splatwarp %s, %s: %zu Gaussians, SH degree %d, format %s%s\n", SPLATWARP_VERSION_STRING,
                    path.c_str(), back.size(), back.shDegree, report.format.c_str(), ok ? "" : " (wrong)");
        bad += !ok;
    }
    return bad == 0 ? 0 : 1;
}
