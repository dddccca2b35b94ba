#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <tuple>

#include "vdb/SampleGrid.h"
#include "vdb/CellLookup.h"
#include "core/Error.h"
#include "field/GaussianMath.h"
#include "demo/DemoModels.h"
#include "sh/SphericalHarmonics.h"

using namespace splatwarp;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// A few Gaussians far apart (random rotation, anisotropic scales, opacities 0.3..0.95), SH degree 1.
GaussianCloud separatedCloud(std::uint32_t seed)
{
    GaussianCloud g;
    g.resize(5, 1);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), s(0.05f, 0.12f), a(0.3f, 0.95f);
    for (std::size_t i = 0; i < g.size(); ++i) {
        g.setMean(i, Vec3f(2.0f * float(i), 0.3f * u(rng), 0.3f * u(rng)));
        g.setRotation(i, Quatf{u(rng), u(rng), u(rng), u(rng)});
        for (int k = 0; k < 3; ++k) g.logScales[3 * i + k] = std::log(s(rng));
        const float alpha = a(rng);
        g.opacities[i] = std::log(alpha / (1.0f - alpha));
        for (int k = 0; k < g.shStride(); ++k) g.shOf(i)[k] = u(rng);
    }
    return g;
}

/// A needle along the (1,1,1) diagonal: its axis-aligned box is a big cube that it fills poorly,
/// so many active cells see no Gaussian at all (cellSkip must find them).
GaussianCloud needleCloud()
{
    GaussianCloud g;
    g.resize(1, 0);
    const Vec3d axis = Vec3d(1, 1, 1) / std::sqrt(3.0);
    // Quaternion rotating x onto the diagonal: half-angle about x cross axis.
    const Vec3d c = cross(Vec3d(1, 0, 0), axis);
    const double angle = std::acos(axis.x), sn = std::sin(angle / 2) / length(c);
    g.setRotation(0, Quatf{float(std::cos(angle / 2)), float(c.x * sn), float(c.y * sn), float(c.z * sn)});
    g.logScales = {std::log(0.5f), std::log(0.01f), std::log(0.01f)};
    g.opacities[0] = 2.0f;
    g.sh[0] = 1.0f;
    return g;
}

/// The test's own box of Gaussian i (double): exact AABB of its cutoff ellipsoid under the filter.
void referenceBox(const GaussianCloud& g, std::size_t i, double filterVariance, double cutoff, Vec3d& lo, Vec3d& hi)
{
    const Quatd q{g.rotations[4 * i], g.rotations[4 * i + 1], g.rotations[4 * i + 2], g.rotations[4 * i + 3]};
    const Mat3d cov = gaussianCovariance(q, Vec3d(g.scale(i))) + Mat3d::identity() * filterVariance;
    const double r = extentRadius(double(g.alpha(i)), cutoff);
    const Vec3d half = ellipsoidHalfExtent(cov, r);
    lo = Vec3d(g.mean(i)) - half;
    hi = Vec3d(g.mean(i)) + half;
}

} // namespace

TEST(SampleGrid, MassMatchesClosedFormForSeparatedGaussians)
{
    const GaussianCloud g = separatedCloud(7);
    for (const float lambda : {0.0f, 0.2f}) {
        SampleGridOptions o;
        o.cellSize = 0.1f; // spacing 0.025 <= smallest sigma / 2: the lattice sum is the integral
        o.cutoff = 1e-5f;  // mass beyond the cutoff ellipsoid: < 1e-3 of the total
        o.lambdaLpf = lambda;
        const SampleGrid grid(g, o);
        const SampleSet& set = grid.samples();
        double lattice = 0.0;
        for (float v : set.targetO) lattice += v;
        lattice *= std::pow(double(set.spacing), 3);
        double closed = 0.0;
        const double filterVariance = double(lambda) * set.spacing * set.spacing;
        for (std::size_t i = 0; i < g.size(); ++i) {
            const Quatd q{g.rotations[4 * i], g.rotations[4 * i + 1], g.rotations[4 * i + 2], g.rotations[4 * i + 3]};
            const Mat3d cov = gaussianCovariance(q, Vec3d(g.scale(i))) + Mat3d::identity() * filterVariance;
            closed += g.alpha(i) * std::pow(2 * kPi, 1.5) * std::sqrt(cov.determinant());
        }
        // Measured relative error: -7.2e-5 (lambda 0 and 0.2): the mass beyond the cutoff.
        EXPECT_NEAR(lattice / closed, 1.0, 1e-3) << "lambda " << lambda;
    }
}

TEST(SampleGrid, EveryExtentLiesInActiveCellsAndGaussianCellHoldsTheCentre)
{
    const GaussianCloud g = makeDemoModel("stripes", {1500, 3});
    SampleGridOptions o;
    o.cells = 24;
    const SampleGrid grid(g, o);
    const SampleSet& set = grid.samples();
    const double h = set.cellSize, filterVariance = o.lambdaLpf * double(set.spacing) * set.spacing;
    ASSERT_EQ(grid.gaussianCell().size(), g.size());
    const test::CellLookup active(grid);
    for (std::size_t i = 0; i < g.size(); ++i) {
        Vec3d lo, hi;
        referenceBox(g, i, filterVariance, o.cutoff, lo, hi);
        // One cell of margin around the box must be active too (the dilation).
        for (int x = int(std::floor(lo.x / h)) - 1; x <= int(std::floor(hi.x / h)) + 1; ++x)
            for (int y = int(std::floor(lo.y / h)) - 1; y <= int(std::floor(hi.y / h)) + 1; ++y)
                for (int z = int(std::floor(lo.z / h)) - 1; z <= int(std::floor(hi.z / h)) + 1; ++z)
                    ASSERT_GE(active(x, y, z), 0) << "Gaussian " << i << " cell " << x << "," << y << "," << z;
        const std::int32_t c = grid.gaussianCell()[i];
        ASSERT_GE(c, 0);
        const Vec3f m = g.mean(i);
        for (int k = 0; k < 3; ++k) {
            EXPECT_LE(grid.cellCoords()[3 * c + k] * h, m[k] + 1e-6 * h);
            EXPECT_GT((grid.cellCoords()[3 * c + k] + 1) * h, m[k] - 1e-6 * h);
        }
        EXPECT_EQ(c, active(int(std::floor(m.x / h)), int(std::floor(m.y / h)), int(std::floor(m.z / h))));
    }
}

TEST(SampleGrid, SamplesSitOnTheCellCentredSubLattice)
{
    const GaussianCloud g = makeDemoModel("stripes", {500, 1});
    SampleGridOptions o;
    o.cells = 8;
    o.samplesPerAxis = 3;
    const SampleGrid grid(g, o);
    const SampleSet& set = grid.samples();
    const int n = 3;
    ASSERT_EQ(set.sampleCount(), set.cellCount() * 27);
    EXPECT_FLOAT_EQ(set.spacing, set.cellSize / 3);
    for (std::size_t s = 0; s < set.sampleCount(); ++s) {
        const std::int32_t c = set.sampleCell[s];
        ASSERT_EQ(std::size_t(c), s / 27);
        const int local[3] = {int(s % 27) / 9, int(s % 9) / 3, int(s % 3)};
        for (int k = 0; k < 3; ++k)
            ASSERT_NEAR(set.restPositions[3 * s + k], (grid.cellCoords()[3 * c + k] * n + local[k] + 0.5) * set.spacing,
                        1e-6);
    }
    EXPECT_EQ(set.warpedPositions, set.restPositions);
    for (std::size_t c = 0; c < set.cellCount(); ++c)
        for (int k = 0; k < 9; ++k) ASSERT_EQ(set.cellGradient[9 * c + k], k % 4 == 0 ? 1.0f : 0.0f);
}

TEST(SampleGrid, CellSkipMatchesNaiveNeighbourhoodTest)
{
    for (const GaussianCloud& g : {needleCloud(), makeDemoModel("stripes", {800, 2})}) {
        SampleGridOptions o;
        o.cells = 20;
        const SampleGrid grid(g, o);
        const SampleSet& set = grid.samples();
        std::map<std::tuple<int, int, int>, std::size_t> cellOf;
        for (std::size_t c = 0; c < set.cellCount(); ++c)
            cellOf[{grid.cellCoords()[3 * c], grid.cellCoords()[3 * c + 1], grid.cellCoords()[3 * c + 2]}] = c;
        const std::size_t perCell = 64, stride = std::size_t(set.featureStride());
        std::vector<bool> nonZero(set.cellCount(), false);
        for (std::size_t s = 0; s < set.sampleCount(); ++s) {
            bool nz = set.targetO[s] != 0.0f;
            for (std::size_t k = 0; k < stride; ++k) nz = nz || set.targetF[s * stride + k] != 0.0f;
            if (nz) nonZero[s / perCell] = true;
        }
        std::size_t skipped = 0;
        for (std::size_t c = 0; c < set.cellCount(); ++c) {
            bool skip = true;
            for (int dx = -1; dx <= 1; ++dx)
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dz = -1; dz <= 1; ++dz) {
                        auto it = cellOf.find({grid.cellCoords()[3 * c] + dx, grid.cellCoords()[3 * c + 1] + dy,
                                               grid.cellCoords()[3 * c + 2] + dz});
                        if (it != cellOf.end() && nonZero[it->second]) skip = false;
                    }
            ASSERT_EQ(set.cellSkip[c], skip ? 1 : 0) << "cell " << c;
            skipped += skip;
        }
        EXPECT_EQ(skipped, grid.stats().skippedCells);
        if (g.size() == 1) EXPECT_GT(skipped, set.cellCount() / 4) << "the needle leaves most of its box empty";
    }
}

TEST(SampleGrid, SerialAndThreadedAgreeExactly)
{
    const GaussianCloud g = makeDemoModel("stripes", {2000, 4});
    SampleGridOptions o;
    o.cells = 16;
    const SampleGrid a(g, o);
    o.threaded = false;
    const SampleGrid b(g, o);
    EXPECT_EQ(a.cellCoords(), b.cellCoords());
    EXPECT_EQ(a.gaussianCell(), b.gaussianCell());
    EXPECT_EQ(a.samples().restPositions, b.samples().restPositions);
    EXPECT_EQ(a.samples().targetF, b.samples().targetF);
    EXPECT_EQ(a.samples().targetO, b.samples().targetO);
    EXPECT_EQ(a.samples().cellSkip, b.samples().cellSkip);
}

TEST(SampleGrid, CellSizeFollowsCellsOrExplicitSizeAndBadOptionsThrow)
{
    const GaussianCloud g = makeDemoModel("stripes", {300, 5});
    SampleGridOptions o;
    o.cellSize = 0.25f;
    EXPECT_FLOAT_EQ(SampleGrid(g, o).samples().cellSize, 0.25f);
    o.cellSize = 0.0f;
    o.cells = 10;
    // h = largest extent of the union of the unfiltered cutoff boxes / cells.
    Vec3d lo(1e30, 1e30, 1e30), hi = -lo;
    for (std::size_t i = 0; i < g.size(); ++i) {
        Vec3d a, b;
        referenceBox(g, i, 0.0, o.cutoff, a, b);
        for (int k = 0; k < 3; ++k) { lo[k] = std::min(lo[k], a[k]); hi[k] = std::max(hi[k], b[k]); }
    }
    const double extent = std::max(hi.x - lo.x, std::max(hi.y - lo.y, hi.z - lo.z));
    // The grid pads its pruning boxes by 1e-3 (PreparedGaussian): up to that much larger.
    EXPECT_NEAR(SampleGrid(g, o).samples().cellSize / (extent / 10), 1.0, 1.5e-3);
    o.samplesPerAxis = 1;
    EXPECT_THROW(SampleGrid(g, o), InputError);
    o.samplesPerAxis = 4;
    o.cutoff = 0.0f;
    EXPECT_THROW(SampleGrid(g, o), InputError);
    EXPECT_THROW(SampleGrid(GaussianCloud{}, SampleGridOptions{}), InputError);
}

// --samples-per-cell auto: the densest n in [4, 8] whose grid fits the sample budget (and the
// memory budget), counted on the 4^3 lattice's cells; the grid is then exactly the explicit n's.
TEST(SampleGrid, AutoSamplesPerCellIsTheDensestWithinTheBudgets)
{
    const GaussianCloud g = makeDemoModel("stripes", {400, 6});
    SampleGridOptions o;
    o.cells = 12;
    const SampleGrid explicitFour(g, o);
    const std::size_t cells4 = explicitFour.stats().cells;
    auto resolved = [&](std::size_t budget, std::size_t memory) {
        SampleGridOptions a = o;
        a.samplesPerAxis = kAutoSamplesPerAxis;
        a.autoSampleBudget = budget;
        a.maxMemoryBytes = memory;
        return SampleGrid(g, a);
    };
    const SampleGrid six = resolved(cells4 * 7 * 7 * 7 - 1, 0);
    ASSERT_EQ(six.options().samplesPerAxis, 6);
    o.samplesPerAxis = 6;
    const SampleGrid explicitSix(g, o);
    EXPECT_LE(six.stats().samples, cells4 * 6 * 6 * 6);
    EXPECT_EQ(six.cellCoords(), explicitSix.cellCoords());
    EXPECT_EQ(six.samples().restPositions, explicitSix.samples().restPositions);
    EXPECT_EQ(six.samples().targetO, explicitSix.samples().targetO);
    EXPECT_FLOAT_EQ(six.targetOptions().filterVariance, explicitSix.targetOptions().filterVariance);

    EXPECT_EQ(resolved(std::size_t(1) << 40, 0).options().samplesPerAxis, 8);          // never past 8
    const SampleGrid four = resolved(cells4 * 5 * 5 * 5 - 1, 0);                       // 5^3 would not fit
    EXPECT_EQ(four.options().samplesPerAxis, 4);
    EXPECT_EQ(four.cellCoords(), explicitFour.cellCoords()); // the topology auto counted on, kept
    EXPECT_EQ(four.samples().targetO, explicitFour.samples().targetO);
    EXPECT_EQ(resolved(1, 0).options().samplesPerAxis, 4);                               // never below 4
    SampleGridOptions five = o;
    five.samplesPerAxis = 5;
    const std::size_t memoryForFive = cells4 * sampleGridBytesPerCell(five, g.shDegree);
    EXPECT_EQ(resolved(std::size_t(1) << 40, memoryForFive).options().samplesPerAxis, 5); // memory decides
}
