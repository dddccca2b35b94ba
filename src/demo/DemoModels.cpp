#include "demo/DemoModels.h"

#include <cmath>
#include <random>

#include "core/Error.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

/// Deterministic uniform numbers independent of the standard library's distributions.
struct Rng {
    std::mt19937 gen;
    explicit Rng(std::uint32_t seed) : gen(seed) {}
    double uniform() { return (gen() + 0.5) / 4294967296.0; }
    double uniform(double a, double b) { return a + (b - a) * uniform(); }
};

/// Store one flat surface Gaussian with axes (along, across, normal) and standard deviations.
void setSurfaceGaussian(GaussianCloud& g, std::size_t i, const Vec3d& p, const Vec3d& along, const Vec3d& normal,
                        double sAlong, double sAcross, double sNormal, double alpha)
{
    const Vec3d across = cross(normal, along);
    Mat3d r;
    for (int a = 0; a < 3; ++a) {
        r.m[a][0] = along[a];
        r.m[a][1] = across[a];
        r.m[a][2] = normal[a];
    }
    g.setMean(i, Vec3f(p));
    const Quatd q = matrixToQuat(r);
    g.setRotation(i, Quatf{float(q.w), float(q.x), float(q.y), float(q.z)});
    g.logScales[3 * i] = float(std::log(sAlong));
    g.logScales[3 * i + 1] = float(std::log(sAcross));
    g.logScales[3 * i + 2] = float(std::log(sNormal));
    g.opacities[i] = float(std::log(alpha / (1.0 - alpha)));
}

void setColour(GaussianCloud& g, std::size_t i, const Vec3d& rgb)
{
    float* sh = g.shOf(i);
    for (int c = 0; c < 3; ++c) sh[c] = float((rgb[c] - 0.5) / kShC0);
}

const double kPalette[8][3] = {{0.90, 0.20, 0.15}, {0.95, 0.85, 0.20}, {0.20, 0.65, 0.30}, {0.15, 0.40, 0.85},
                               {0.95, 0.95, 0.95}, {0.55, 0.25, 0.70}, {0.95, 0.55, 0.10}, {0.10, 0.10, 0.12}};

GaussianCloud makeStripes(const DemoModelOptions& o)
{
    const std::size_t n = o.count ? o.count : 20000;
    const double lx = 4.0, ly = 1.0, lz = 1.0;
    GaussianCloud g;
    g.resize(n, 1);
    Rng rng(o.seed);
    // Faces: 4 long faces (area lx*1 each) + 2 end caps (1*1): pick by area.
    const double areas[6] = {lx * lz, lx * lz, lx * ly, lx * ly, ly * lz, ly * lz};
    const double total = areas[0] + areas[1] + areas[2] + areas[3] + areas[4] + areas[5];
    const double spacing = std::sqrt(total / double(n));
    for (std::size_t i = 0; i < n; ++i) {
        double u = rng.uniform() * total;
        int f = 0;
        while (f < 5 && u > areas[f]) u -= areas[f++];
        const double a = rng.uniform(-0.5, 0.5), b = rng.uniform(-0.5, 0.5);
        Vec3d p, normal, along(1, 0, 0);
        switch (f) {
        case 0: p = Vec3d(a * lx, 0.5 * ly, b * lz); normal = Vec3d(0, 1, 0); break;
        case 1: p = Vec3d(a * lx, -0.5 * ly, b * lz); normal = Vec3d(0, -1, 0); break;
        case 2: p = Vec3d(a * lx, b * ly, 0.5 * lz); normal = Vec3d(0, 0, 1); break;
        case 3: p = Vec3d(a * lx, b * ly, -0.5 * lz); normal = Vec3d(0, 0, -1); break;
        case 4: p = Vec3d(0.5 * lx, a * ly, b * lz); normal = Vec3d(1, 0, 0); along = Vec3d(0, 1, 0); break;
        default: p = Vec3d(-0.5 * lx, a * ly, b * lz); normal = Vec3d(-1, 0, 0); along = Vec3d(0, 0, 1); break;
        }
        // Trained 3DGS surfaces: flat (normal scale ~1/10 of tangent), elongated along the surface.
        const double sAlong = spacing * rng.uniform(0.9, 1.6), sAcross = spacing * rng.uniform(0.45, 0.7);
        setSurfaceGaussian(g, i, p, along, normal, sAlong, sAcross, 0.1 * sAcross, rng.uniform(0.6, 0.97));
        const int band = std::min(7, int((p.x / lx + 0.5) * 8.0));
        const double* c = kPalette[band];
        setColour(g, i, Vec3d(c[0], c[1], c[2]) * rng.uniform(0.92, 1.0));
        // View-dependent sheen in SH band 1: one coherent lobe per colour band (as trained
        // models show on glossy surfaces), stronger on the odd bands, plus a little noise.
        float* sh = g.shOf(i);
        const double k = (band % 2) ? 0.2 : 0.06;
        const Vec3d lobe = Vec3d(std::cos(1.3 * band), std::sin(1.3 * band), 0.5 * std::cos(0.7 * band));
        for (int j = 1; j < 4; ++j)
            for (int ch = 0; ch < 3; ++ch) sh[3 * j + ch] = float(k * lobe[j - 1] + 0.02 * rng.uniform(-1.0, 1.0));
    }
    return g;
}

GaussianCloud makeRing(const DemoModelOptions& o)
{
    const std::size_t n = o.count ? o.count : 16000;
    const double bigR = 1.0, smallR = 0.3;
    GaussianCloud g;
    g.resize(n, 0);
    Rng rng(o.seed + 7919);
    const double area = 4 * M_PI * M_PI * bigR * smallR;
    const double spacing = std::sqrt(area / double(n));
    for (std::size_t i = 0; i < n; ++i) {
        // Rejection sampling for uniform area density on the torus.
        double u, v;
        do {
            u = rng.uniform(0, 2 * M_PI);
            v = rng.uniform(0, 2 * M_PI);
        } while (rng.uniform() * (bigR + smallR) > bigR + smallR * std::cos(v));
        const Vec3d normal(std::cos(v) * std::cos(u), std::cos(v) * std::sin(u), std::sin(v));
        const Vec3d p = Vec3d(bigR * std::cos(u), bigR * std::sin(u), 0.0) + normal * smallR;
        const Vec3d along(-std::sin(u), std::cos(u), 0.0);
        const double sAlong = spacing * rng.uniform(0.9, 1.5), sAcross = spacing * rng.uniform(0.45, 0.7);
        setSurfaceGaussian(g, i, p, along, normal, sAlong, sAcross, 0.1 * sAcross, rng.uniform(0.6, 0.97));
        const double h = u / (2 * M_PI);
        setColour(g, i, Vec3d(0.5 + 0.4 * std::cos(2 * M_PI * h), 0.5 + 0.4 * std::cos(2 * M_PI * (h - 1.0 / 3)),
                              0.5 + 0.4 * std::cos(2 * M_PI * (h - 2.0 / 3))));
    }
    return g;
}

} // namespace

std::vector<std::string> demoModelNames() { return {"stripes", "ring"}; }

GaussianCloud makeDemoModel(const std::string& name, const DemoModelOptions& options)
{
    if (name == "stripes") return makeStripes(options);
    if (name == "ring") return makeRing(options);
    throw InputError(msg("unknown sample '", name, "' (known: stripes, ring)"));
}

} // namespace splatwarp
