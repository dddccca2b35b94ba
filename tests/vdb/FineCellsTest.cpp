// Fine cells (SampleGridOptions::fineBelow): (2n)^3 samples where the Gaussians are small, with
// their Gaussians' rest and Stage II filter at the fine spacing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>
#include <tuple>

#include "vdb/SampleGrid.h"
#include "vdb/VdbExport.h"
#include "core/Error.h"
#include "deform/WarpMath.h"
#include "field/FieldTestModels.h"
#include "stage2/StageTwo.h"
#include "stage2/StageTwoSetup.h"
#include "support/CellListTargets.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

constexpr int kN = 2;

GaussianCloud mixedCloud() { return mixedSizeCloud(); }

SampleGridOptions fineOptions(float fineBelow = 1.0f)
{
    SampleGridOptions o;
    o.cells = 12;
    o.samplesPerAxis = kN;
    o.fineBelow = fineBelow;
    return o;
}

/// The largest absolute difference of two arrays of one size.
double largestChange(const std::vector<float>& a, const std::vector<float>& b)
{
    double d = 0;
    for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) d = std::max(d, double(std::fabs(a[i] - b[i])));
    return a.size() == b.size() ? d : HUGE_VAL;
}

bool sameBits(const std::vector<float>& a, const std::vector<float>& b)
{
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

/// The test's own criterion: the upper median of the largest scales of the Gaussians centred in each cell.
std::vector<bool> naiveSmallCells(const GaussianCloud& g, const SampleGrid& grid, double below)
{
    std::vector<std::vector<float>> largest(grid.samples().cellCount());
    for (std::size_t i = 0; i < g.size(); ++i) {
        const Vec3f s = g.scale(i);
        largest[std::size_t(grid.gaussianCell()[i])].push_back(std::max({s.x, s.y, s.z}));
    }
    std::vector<bool> small(largest.size(), false);
    for (std::size_t c = 0; c < largest.size(); ++c) {
        if (largest[c].empty()) continue;
        std::sort(largest[c].begin(), largest[c].end());
        small[c] = largest[c][largest[c].size() / 2] < below;
    }
    return small;
}

} // namespace

TEST(FineCells, SmallGaussiansCellsHoldTheFineLatticeOctantByOctant)
{
    const GaussianCloud g = mixedCloud();
    const SampleGrid grid(g, fineOptions());
    const SampleSet& set = grid.samples();
    ASSERT_FALSE(set.uniform());
    const std::vector<bool> small = naiveSmallCells(g, grid, double(set.cellSize) / kN);
    std::size_t fine = 0, samples = 0;
    for (std::size_t c = 0; c < set.cellCount(); ++c) {
        const int axis = set.axisOf(c);
        ASSERT_EQ(axis, small[c] ? 2 * kN : kN) << "cell " << c;
        fine += axis == 2 * kN;
        const std::size_t s0 = set.firstSampleOf(c), count = std::size_t(axis) * axis * axis;
        ASSERT_EQ(set.firstSampleOf(c + 1), s0 + count);
        samples += count;
        const double spacing = double(set.cellSize) / axis;
        EXPECT_FLOAT_EQ(set.spacingOf(c), float(spacing));
        // Every lattice point of the cell once; each run of n^3 inside one octant.
        std::set<std::tuple<int, int, int>> seen;
        for (std::size_t s = s0; s < s0 + count; ++s) {
            ASSERT_EQ(set.sampleCell[s], std::int32_t(c));
            int local[3];
            for (int k = 0; k < 3; ++k) {
                local[k] = int(std::lround(set.restPositions[3 * s + k] / spacing - 0.5)) - grid.cellCoords()[3 * c + k] * axis;
                ASSERT_GE(local[k], 0);
                ASSERT_LT(local[k], axis);
                const int octant = ((s - s0) / (kN * kN * kN)) >> (2 - k) & 1;
                if (axis == 2 * kN) ASSERT_EQ(local[k] / kN, octant) << "sample " << s;
            }
            seen.insert({local[0], local[1], local[2]});
        }
        EXPECT_EQ(seen.size(), count);
        // The gradient's corner samples are the cell's extreme samples.
        for (int q = 0; q < 8; ++q) {
            const std::size_t s = cellCornerSample(s0, axis, kN, q);
            for (int k = 0; k < 3; ++k) {
                const double expected = (grid.cellCoords()[3 * c + k] * axis + ((q >> (2 - k)) & 1) * (axis - 1) + 0.5) * spacing;
                ASSERT_NEAR(set.restPositions[3 * s + k], expected, 1e-6);
            }
        }
    }
    EXPECT_GT(fine, 0u);
    EXPECT_LT(fine, set.cellCount());
    EXPECT_EQ(grid.stats().fineCells, fine);
    EXPECT_EQ(grid.stats().samples, samples);
    EXPECT_EQ(set.sampleCount(), samples);
    EXPECT_EQ(grid.stats().fineSamplesAdded, fine * 7 * kN * kN * kN);
}

TEST(FineCells, NoSmallCellKeepsTheUniformLatticeBitForBit)
{
    const GaussianCloud g = mixedCloud();
    const SampleGrid uniform(g, fineOptions(0.0f)), none(g, fineOptions(1e-4f));
    EXPECT_TRUE(uniform.samples().uniform());
    EXPECT_TRUE(none.samples().uniform());
    EXPECT_EQ(none.stats().fineCells, 0u);
    EXPECT_TRUE(sameBits(uniform.samples().restPositions, none.samples().restPositions));
    EXPECT_TRUE(sameBits(uniform.samples().targetF, none.samples().targetF));
    EXPECT_TRUE(sameBits(uniform.samples().targetO, none.samples().targetO));
    EXPECT_EQ(uniform.samples().cellSkip, none.samples().cellSkip);
    // The coarse cells of a grid with fine cells keep their samples' positions.
    const SampleGrid fine(g, fineOptions());
    ASSERT_EQ(fine.cellCoords(), uniform.cellCoords());
    const SampleSet& a = uniform.samples();
    const SampleSet& b = fine.samples();
    for (std::size_t c = 0; c < a.cellCount(); ++c) {
        if (b.axisOf(c) != kN) continue;
        for (std::size_t k = 0; k < 3 * kN * kN * kN; ++k)
            ASSERT_EQ(a.restPositions[3 * a.firstSampleOf(c) + k], b.restPositions[3 * b.firstSampleOf(c) + k]);
    }
}

TEST(FineCells, StageTwoFilterUsesTheSpacingOfTheGaussiansCell)
{
    const GaussianCloud g = mixedCloud();
    const SampleGrid grid(g, fineOptions());
    const SampleSet& set = grid.samples();
    StageTwoOptions o;
    const std::vector<std::uint8_t> moving(g.size(), 1);
    const StageTwoSetup st = setupStageTwo(g, set, moving, grid.gaussianCell(), o, false);
    const double h = set.cellSize;
    std::size_t fine = 0;
    for (std::size_t i = 0; i < g.size(); ++i) {
        const bool inFine = set.axisOf(std::size_t(grid.gaussianCell()[i])) == 2 * kN;
        fine += inFine;
        const double s = h / (inFine ? 2 * kN : kN);
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
                ASSERT_NEAR(st.filter[i].m[a][b], a == b ? double(o.lambdaLpf) * s * s : 0.0, 1e-6 * double(o.lambdaLpf) * s * s);
    }
    EXPECT_GT(fine, 0u);
    EXPECT_LT(fine, g.size());
}

// At rest (identity gradients) the model is its own targets: the rest targets use each Gaussian's
// filter at its cell's spacing, as Stage II does. Every step climbs (rejected), the model is kept.
TEST(FineCells, AtRestTheModelEqualsItsTargets)
{
    const GaussianCloud g = mixedCloud();
    const SampleGrid grid(g, fineOptions());
    ASSERT_GT(grid.stats().fineCells, 0u);
    const std::vector<std::uint8_t> moving(g.size(), 1);
    StageTwoOptions o;
    o.iterations = 20;
    GaussianCloud fitted = g;
    const StageTwoReport r = optimiseStageTwo(fitted, grid.samples(), moving, grid.gaussianCell(), o);
    // The same model against the targets with the coarse filter for every Gaussian: the mismatch
    // the per-Gaussian filter removes (the targets of fine cells are sharper).
    SampleSet coarse = grid.samples();
    coarse.spacing = coarse.cellSize / (2 * kN); // coarse cells' Gaussians now get the fine filter
    StageTwoOptions once = o;
    once.iterations = 0;
    GaussianCloud same = g;
    const StageTwoReport w = optimiseStageTwo(same, coarse, moving, grid.gaussianCell(), once);
    const double e0 = r.energies.front().total, wrong = w.energies.front().total;
    std::printf("  energy at rest %.3g; with the fine filter on the coarse cells' Gaussians too %.3g\n", e0, wrong);
    EXPECT_LT(e0, 1e-4 * wrong);
    // Stage II keeps it: the held energy never rises, and the steps it accepts at this
    // rounding-level energy move nothing by more than a rounding-level amount.
    EXPECT_LE(r.bestEnergy, e0);
    EXPECT_LT(largestChange(fitted.means, g.means), 1e-4);
    EXPECT_LT(largestChange(fitted.logScales, g.logScales), 1e-4);
    EXPECT_LT(largestChange(fitted.opacities, g.opacities), 1e-4);
}

TEST(FineCells, VdbExportRefusesAGridWithFineCells)
{
    const SampleGrid grid(mixedCloud(), fineOptions());
    const std::string path = ::testing::TempDir() + "fine-cells.vdb";
    EXPECT_THROW(writeSampleGridVdb(path, grid), InputError);
    EXPECT_FALSE(std::ifstream(path).good());
}
