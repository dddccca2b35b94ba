// The NanoVDB cell index grid and the GPU sample-target algorithm run on the CPU: the
// per-element functions of field/CellTargetMath.h looped over host arrays in the GPU layout
// (what kernels/FeaturesCuda.cu launches) against SampleGrid's CPU targets. Both sum the same
// float terms in the same order, so they must agree bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <vector>

#include "SampleGrid.h"
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

struct HostTargets {
    std::vector<float> f, o;
    std::uint64_t contributing = 0, pairs = 0;
};

/// The GPU algorithm over host arrays: count, exclusive scan, fill, stable sort by cell, mark
/// ranges, evaluate every sample (index loops where the kernels have threads).
HostTargets cellListTargets(const GaussianCloud& cloud, const SampleGrid& grid)
{
    const SampleSet& set = grid.samples();
    const FeatureOptions& fo = grid.targetOptions();
    const std::vector<PreparedGaussian> g = prepareCloud(cloud, double(fo.filterVariance), fo.cutoff, false);
    const CellIndexGrid bytes = grid.nanoIndexGrid();
    const NanoCellGrid& nano = *nanoCellGrid(bytes);
    const double h = double(set.cellSize);
    const std::size_t n = g.size(), m = set.restPositions.size() / 3, cells = grid.cellCoords().size() / 3;

    std::vector<std::uint64_t> offsets(n + 1, 0);
    for (std::size_t i = 0; i < n; ++i) offsets[i + 1] = offsets[i] + gaussianCellPairs(std::uint32_t(i), g[i], h, nano, nullptr, nullptr);
    const std::size_t pairs = offsets[n];
    std::vector<std::uint32_t> cellOf(pairs), owner(pairs);
    for (std::size_t i = 0; i < n; ++i)
        EXPECT_EQ(gaussianCellPairs(std::uint32_t(i), g[i], h, nano, cellOf.data() + offsets[i], owner.data() + offsets[i]),
                  offsets[i + 1] - offsets[i]);
    std::vector<std::size_t> order(pairs);
    std::iota(order.begin(), order.end(), std::size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return cellOf[a] < cellOf[b]; });
    std::vector<std::uint32_t> sortedCells(pairs), sortedOwners(pairs);
    for (std::size_t p = 0; p < pairs; ++p) {
        sortedCells[p] = cellOf[order[p]];
        sortedOwners[p] = owner[order[p]];
    }
    std::vector<std::uint32_t> start(cells, 0), end(cells, 0);
    for (std::size_t p = 0; p < pairs; ++p) markCellRange(p, sortedCells.data(), pairs, start.data(), end.data());
    for (std::size_t c = 0; c < cells; ++c)
        for (std::uint32_t p = start[c]; p + 1 < end[c]; ++p)
            EXPECT_LT(sortedOwners[p], sortedOwners[p + 1]) << "cell " << c << ": Gaussians not strictly ascending";

    CellTargetView v;
    v.gaussians = g.data();
    v.sh = cloud.sh.data();
    v.shStride = cloud.shStride();
    v.cutoff = fo.cutoff;
    v.positions = set.restPositions.data();
    v.sampleCell = set.sampleCell.data();
    v.cellStart = start.data();
    v.cellEnd = end.data();
    v.cellGaussians = sortedOwners.data();
    HostTargets out;
    out.f.assign(m * std::size_t(v.shStride), -1.0f); // overwritten everywhere
    out.o.assign(m, -1.0f);
    out.pairs = pairs;
    for (std::size_t s = 0; s < m; ++s)
        out.contributing += evaluateCellSample(s, v, out.f.data() + s * std::size_t(v.shStride), out.o[s]);
    return out;
}

void expectSameTargets(const GaussianCloud& cloud, const SampleGridOptions& options)
{
    const SampleGrid grid(cloud, options);
    ASSERT_EQ(grid.stats().device, Device::Cpu);
    const HostTargets t = cellListTargets(cloud, grid);
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
