// The NanoVDB cell index grid and the GPU sample-target algorithm run on the CPU: the
// per-element functions of field/CellTargetMath.h looped over host arrays in the GPU layout
// (what kernels/FeaturesCuda.cu launches) against SampleGrid's CPU targets. Both sum the same
// float terms in the same order, so they must agree bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <vector>

#include "vdb/SampleGrid.h"
#include "support/CellListTargets.h"
#include "vdb/CellLookup.h"
#include "field/CellTargetMath.h"
#include "field/FeatureField.h"
#include "field/FieldTestModels.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

namespace {

/// Cell index at integer cell coordinates in the NanoVDB grid (-1: not active).
std::int32_t lookupCell(const NanoCellGrid& grid, int i, int j, int k)
{
    return grid.tree().getValue(nanovdb::Coord(i, j, k));
}

/// Every active cell and its 26 neighbours: NanoVDB lookup == the cells SampleGrid lists (-1 outside).
void expectSameLookups(const SampleGrid& grid)
{
    const CellIndexGrid bytes = grid.nanoIndexGrid();
    ASSERT_FALSE(bytes.empty());
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(bytes.data()) % 32, 0u) << "NanoVDB needs 32-byte alignment";
    const NanoCellGrid* nano = nanoCellGrid(bytes);
    ASSERT_NE(nano, nullptr);
    const std::vector<std::int32_t>& ijk = grid.cellCoords();
    const std::size_t cells = ijk.size() / 3;
    const test::CellLookup listed(grid);
    std::size_t outside = 0;
    for (std::size_t c = 0; c < cells; ++c) {
        ASSERT_EQ(lookupCell(*nano, ijk[3 * c], ijk[3 * c + 1], ijk[3 * c + 2]), std::int32_t(c));
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    const int i = ijk[3 * c] + dx, j = ijk[3 * c + 1] + dy, k = ijk[3 * c + 2] + dz;
                    const std::int32_t expected = listed(i, j, k);
                    ASSERT_EQ(lookupCell(*nano, i, j, k), expected) << "cell " << i << "," << j << "," << k;
                    outside += expected < 0 ? 1 : 0;
                }
    }
    EXPECT_GT(outside, 0u) << "the boundary of the topology (background -1) was never looked up";
}

void expectSameTargets(const GaussianCloud& cloud, const SampleGridOptions& options)
{
    const SampleGrid grid(cloud, options);
    ASSERT_EQ(grid.stats().device, Device::Cpu);
    const test::GridTargetsProblem problem(cloud, grid);
    const test::HostTargets t = test::cellListTargets(problem.p);
    const SampleSet& set = grid.samples();
    ASSERT_EQ(t.f.size(), set.targetF.size());
    ASSERT_EQ(t.o.size(), set.targetO.size());
    for (std::size_t k = 0; k < t.f.size(); ++k) ASSERT_EQ(t.f[k], set.targetF[k]) << "feature " << k;
    for (std::size_t s = 0; s < t.o.size(); ++s) ASSERT_EQ(t.o[s], set.targetO[s]) << "opacity " << s;
    EXPECT_EQ(t.contributing, grid.stats().pairsContributing);
    EXPECT_GT(t.contributing, 0u);
    EXPECT_GE(t.pairs, 1u);
}

} // namespace

TEST(CellIndexGrid, NanoLookupsEqualOpenVdbOnStripes)
{
    SampleGridOptions o;
    o.cells = 24;
    expectSameLookups(SampleGrid(makeDemoModel("stripes"), o));
}

TEST(CellIndexGrid, NanoLookupsEqualOpenVdbOnRandomCloud)
{
    SampleGridOptions o;
    o.cells = 20;
    o.samplesPerAxis = 2;
    expectSameLookups(SampleGrid(test::randomCloud(300, 0, 11u, 1.0f), o));
}

TEST(CellIndexGrid, EmptyOrForeignBytesAreRejected)
{
    EXPECT_EQ(nanoCellGrid(CellIndexGrid{}), nullptr);
    const std::vector<unsigned char> junk(4096, 7);
    CellIndexGrid g;
    g.assign(junk.data(), junk.size());
    EXPECT_EQ(nanoCellGrid(g), nullptr);
}

TEST(CellIndexGrid, CellListTargetsEqualCpuOnStripes)
{
    SampleGridOptions o;
    o.cells = 24;
    expectSameTargets(makeDemoModel("stripes"), o);
}

TEST(CellIndexGrid, CellListTargetsEqualCpuOnRandomCloudDegree0And3)
{
    SampleGridOptions o;
    o.cells = 16;
    o.samplesPerAxis = 3;
    for (const int degree : {0, 3}) {
        SCOPED_TRACE(degree);
        expectSameTargets(test::randomCloud(200, degree, 5u + std::uint32_t(degree), 1.0f), o);
    }
}

TEST(CellIndexGrid, CellListTargetsEqualCpuWithoutFilterAndHighCutoff)
{
    SampleGridOptions o;
    o.cells = 12;
    o.lambdaLpf = 0.0f;
    o.cutoff = 0.05f; // many Gaussians (logit < ~-2.9) never contribute and emit no pairs
    expectSameTargets(test::randomCloud(150, 1, 23u, 1.0f), o);
}

// pairsTested counts each sample against its own cell's list, so fine cells ((2n)^3 samples) count
// 8x: the sum over cells of (list length) x (that cell's samples), not pairs x (M / C).
TEST(CellIndexGrid, PairsTestedCountEachCellsOwnSamples)
{
    SampleGridOptions o;
    o.cells = 12;
    o.samplesPerAxis = 2;
    o.fineBelow = 1.0f;
    const GaussianCloud cloud = test::mixedSizeCloud();
    const SampleGrid grid(cloud, o);
    const SampleSet& set = grid.samples();
    ASSERT_GT(grid.stats().fineCells, 0u);
    ASSERT_LT(grid.stats().fineCells, set.cellCount());
    ASSERT_NE(set.sampleCount() % set.cellCount(), 0u) << "premise: the cells do not hold equal sample counts";
    const test::GridTargetsProblem problem(cloud, grid);
    const test::HostTargets t = test::cellListTargets(problem.p);
    std::vector<std::uint32_t> sortedCells, owners;
    test::sortedCellPairs(problem.p, sortedCells, owners);
    std::vector<std::uint64_t> listLength(set.cellCount(), 0);
    for (const std::uint32_t c : sortedCells) ++listLength[c];
    std::uint64_t expected = 0;
    for (std::size_t c = 0; c < set.cellCount(); ++c) expected += listLength[c] * (set.firstSampleOf(c + 1) - set.firstSampleOf(c));
    EXPECT_EQ(t.tested, expected);
    EXPECT_NE(t.tested, t.pairs * (set.sampleCount() / set.cellCount())) << "the uniform formula must not fit here";
    EXPECT_GE(t.tested, t.contributing);
    EXPECT_GT(t.contributing, 0u);
}
