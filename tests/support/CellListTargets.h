#pragma once
/// @file CellListTargets.h
/// @brief The GPU sample-target algorithm (kernels/FeaturesCuda.cu) over host arrays, for the CPU
///        tests (tests/vdb/CellIndexGridTest.cpp) and as the reference of the CUDA ones: count,
///        exclusive scan, fill, stable sort by cell, mark ranges, evaluate every sample, with the
///        per-element functions of field/CellTargetMath.h where the kernels have threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

#include "vdb/SampleGrid.h"
#include "field/CellTargetMath.h"
#include "field/FeatureDevice.h"
#include "field/FeatureField.h"
#include "field/FieldTestModels.h"

namespace splatwarp::test {

struct HostTargets {
    std::vector<float> f, o;
    std::uint64_t contributing = 0, pairs = 0, tested = 0;
};

/// @brief A SampleTargetsProblem over a grid's cells and samples, with `cloud` prepared with the
///        grid's rest filter; owns the arrays the problem points into.
struct GridTargetsProblem {
    std::vector<PreparedGaussian> prepared;
    CellIndexGrid index;
    SampleTargetsProblem p;

    GridTargetsProblem(const GridTargetsProblem&) = delete; // p points into this object
    GridTargetsProblem& operator=(const GridTargetsProblem&) = delete;
    GridTargetsProblem(const GaussianCloud& cloud, const SampleGrid& grid)
    {
        const FeatureOptions& fo = grid.targetOptions();
        prepared = prepareCloud(cloud, double(fo.filterVariance), fo.cutoff, false);
        index = grid.nanoIndexGrid();
        const SampleSet& set = grid.samples();
        p.cloud = preparedView(prepared, cloud, fo.cutoff);
        p.index = &index;
        p.cellSize = double(set.cellSize);
        p.positions = set.restPositions.data();
        p.sampleCell = set.sampleCell.data();
        p.samples = set.restPositions.size() / 3;
        p.cells = grid.cellCoords().size() / 3;
    }
};

/// (cell, Gaussian) pairs sorted by cell, Gaussians ascending within a cell (as the radix sort).
inline void sortedCellPairs(const SampleTargetsProblem& p, std::vector<std::uint32_t>& sortedCells,
                            std::vector<std::uint32_t>& sortedOwners)
{
    const NanoCellGrid& nano = *nanoCellGrid(*p.index);
    const std::size_t n = p.cloud.count;
    std::vector<std::uint64_t> offsets(n + 1, 0);
    for (std::size_t i = 0; i < n; ++i)
        offsets[i + 1] = offsets[i] + gaussianCellPairs(std::uint32_t(i), p.cloud.gaussians[i], p.cellSize, nano, nullptr, nullptr);
    const std::size_t pairs = offsets[n];
    std::vector<std::uint32_t> cellOf(pairs), owner(pairs);
    for (std::size_t i = 0; i < n; ++i)
        EXPECT_EQ(gaussianCellPairs(std::uint32_t(i), p.cloud.gaussians[i], p.cellSize, nano, cellOf.data() + offsets[i],
                                    owner.data() + offsets[i]),
                  offsets[i + 1] - offsets[i]);
    std::vector<std::size_t> order(pairs);
    std::iota(order.begin(), order.end(), std::size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return cellOf[a] < cellOf[b]; });
    sortedCells.resize(pairs);
    sortedOwners.resize(pairs);
    for (std::size_t k = 0; k < pairs; ++k) {
        sortedCells[k] = cellOf[order[k]];
        sortedOwners[k] = owner[order[k]];
    }
}

/// @brief The targets, counted pairs and tested candidates of a problem, as the GPU computes them.
inline HostTargets cellListTargets(const SampleTargetsProblem& p)
{
    std::vector<std::uint32_t> sortedCells, sortedOwners;
    sortedCellPairs(p, sortedCells, sortedOwners);
    const std::size_t pairs = sortedCells.size();
    std::vector<std::uint32_t> start(p.cells, 0), end(p.cells, 0);
    for (std::size_t k = 0; k < pairs; ++k) markCellRange(k, sortedCells.data(), pairs, start.data(), end.data());
    for (std::size_t c = 0; c < p.cells; ++c)
        for (std::uint32_t k = start[c]; k + 1 < end[c]; ++k)
            EXPECT_LT(sortedOwners[k], sortedOwners[k + 1]) << "cell " << c << ": Gaussians not strictly ascending";
    CellTargetView v;
    v.gaussians = p.cloud.gaussians;
    v.sh = p.cloud.sh;
    v.shStride = p.cloud.shStride;
    v.cutoff = p.cloud.cutoff;
    v.positions = p.positions;
    v.sampleCell = p.sampleCell;
    v.cellStart = start.data();
    v.cellEnd = end.data();
    v.cellGaussians = sortedOwners.data();
    HostTargets out;
    const std::size_t stride = std::size_t(v.shStride);
    out.f.assign(p.samples * stride, -1.0f); // overwritten everywhere
    out.o.assign(p.samples, -1.0f);
    out.pairs = pairs;
    for (std::size_t s = 0; s < p.samples; ++s) {
        out.tested += cellSampleCandidates(s, v);
        out.contributing += evaluateCellSample(s, v, out.f.data() + s * stride, out.o[s]);
    }
    return out;
}

/// @brief Small Gaussians (scales 0.004..0.01) at x < 0, large ones (0.08..0.2) at x > 0: with
///        SampleGridOptions::fineBelow the cells at x < 0 are fine, (2n)^3 samples, the others n^3.
inline GaussianCloud mixedSizeCloud()
{
    const GaussianCloud small = randomCloud(300, 1, 11, 0.45f, 0.004f, 0.01f);
    const GaussianCloud large = randomCloud(80, 1, 12, 0.45f, 0.08f, 0.2f);
    GaussianCloud g = small;
    for (std::size_t i = 0; i < large.size(); ++i) g.append(large, i);
    for (std::size_t i = 0; i < g.size(); ++i) {
        const Vec3f p = g.mean(i);
        g.setMean(i, Vec3f(p.x + (i < small.size() ? -0.5f : 0.5f), p.y, p.z));
    }
    return g;
}

} // namespace splatwarp::test
