#pragma once
/// @file StageTwoTestProblem.h
/// @brief A synthetic Stage II problem without VDB: a lattice of cells (n^3 samples each)
///        around a small random cloud, targets = features of a known target cloud (the cloud
///        moved and rotated rigidly, see rigidlyMoved()), every cell gradient identity.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "field/FeatureField.h"
#include "field/FieldTestModels.h"
#include "field/SampleSet.h"
#include "field/RigidMotion.h"
#include "stage2/StageTwoOptions.h"

namespace splatwarp::test {

/// @brief Cells of edge h covering [-half, half]^3 (cellsPerAxis per axis), n^3 samples per
///        cell; targets from `target` with the isotropic rest filter lambda*spacing^2; cells
///        with zero target opacity in themselves and all 26 neighbours are skipped.
inline SampleSet latticeSampleSet(const GaussianCloud& target, int cellsPerAxis, float half, int n,
                                  const StageTwoOptions& o)
{
    SampleSet s;
    s.shDegree = target.shDegree;
    s.samplesPerAxis = n;
    s.cellSize = 2.0f * half / float(cellsPerAxis);
    s.spacing = s.cellSize / float(n);
    const int c = cellsPerAxis;
    for (int cx = 0; cx < c; ++cx)
        for (int cy = 0; cy < c; ++cy)
            for (int cz = 0; cz < c; ++cz) {
                const std::int32_t cell = std::int32_t((cx * c + cy) * c + cz);
                for (int a = 0; a < n; ++a)
                    for (int b = 0; b < n; ++b)
                        for (int d = 0; d < n; ++d) {
                            s.restPositions.push_back(-half + s.cellSize * float(cx) + s.spacing * (float(a) + 0.5f));
                            s.restPositions.push_back(-half + s.cellSize * float(cy) + s.spacing * (float(b) + 0.5f));
                            s.restPositions.push_back(-half + s.cellSize * float(cz) + s.spacing * (float(d) + 0.5f));
                            s.sampleCell.push_back(cell);
                        }
            }
    s.warpedPositions = s.restPositions;
    const std::size_t m = s.restPositions.size() / 3;
    FeatureOptions fo;
    fo.cutoff = o.cutoff;
    fo.filterVariance = o.lowPassFilter ? o.lambdaLpf * s.spacing * s.spacing : 0.0f;
    evaluateSampleTargets(target, s, fo);
    const std::size_t cells = std::size_t(c) * std::size_t(c) * std::size_t(c);
    s.cellGradient.assign(9 * cells, 0.0f);
    for (std::size_t k = 0; k < cells; ++k) s.cellGradient[9 * k] = s.cellGradient[9 * k + 4] = s.cellGradient[9 * k + 8] = 1.0f;
    std::vector<std::uint8_t> empty(cells, 1);
    for (std::size_t j = 0; j < m; ++j)
        if (s.targetO[j] != 0.0f) empty[std::size_t(s.sampleCell[j])] = 0;
    s.cellSkip.assign(cells, 1);
    for (int cx = 0; cx < c; ++cx)
        for (int cy = 0; cy < c; ++cy)
            for (int cz = 0; cz < c; ++cz)
                for (int dx = -1; dx <= 1; ++dx)
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dz = -1; dz <= 1; ++dz) {
                            const int x = cx + dx, y = cy + dy, z = cz + dz;
                            if (x < 0 || y < 0 || z < 0 || x >= c || y >= c || z >= c) continue;
                            if (!empty[std::size_t((x * c + y) * c + z)])
                                s.cellSkip[std::size_t((cx * c + cy) * c + cz)] = 0;
                        }
    return s;
}

/// @brief Rest cell of each Gaussian in a lattice built by latticeSampleSet().
inline std::vector<std::int32_t> latticeCells(const GaussianCloud& g, int cellsPerAxis, float half)
{
    std::vector<std::int32_t> cells(g.size());
    const float h = 2.0f * half / float(cellsPerAxis);
    for (std::size_t i = 0; i < g.size(); ++i) {
        int idx[3];
        for (int a = 0; a < 3; ++a)
            idx[a] = std::clamp(int(std::floor((g.mean(i)[a] + half) / h)), 0, cellsPerAxis - 1);
        cells[i] = std::int32_t((idx[0] * cellsPerAxis + idx[1]) * cellsPerAxis + idx[2]);
    }
    return cells;
}

/// @brief A whole Stage II problem: a random start cloud (all moving), its lattice sample set
///        with targets from the cloud moved by (r, t), and the rest cells.
struct RigidStageTwoProblem {
    GaussianCloud start;
    SampleSet samples;
    std::vector<std::uint8_t> moving;
    std::vector<std::int32_t> cells;
    StageTwoOptions options;
};

/// @brief See RigidStageTwoProblem; the cloud is randomCloud(count, degree, seed, extent, 0.04..0.12 scales)
///        and the lattice latticeSampleSet(target, cellsPerAxis, half, 2, options).
inline RigidStageTwoProblem rigidStageTwoProblem(std::size_t count, int degree, std::uint32_t seed, float extent,
                                                 const Mat3d& r, const Vec3d& t, int cellsPerAxis, float half,
                                                 const StageTwoOptions& options = {})
{
    RigidStageTwoProblem p;
    p.options = options;
    p.start = randomCloud(count, degree, seed, extent, 0.04f, 0.12f);
    p.samples = latticeSampleSet(rigidlyMoved(p.start, r, t), cellsPerAxis, half, 2, options);
    p.moving.assign(count, 1);
    p.cells = latticeCells(p.start, cellsPerAxis, half);
    return p;
}


/// @brief ||a - b|| / ||b|| in double (||a - b|| when b is zero); fails the test on a size
///        mismatch or any non-finite value of a.
inline double relativeError(const std::vector<float>& a, const std::vector<double>& b)
{
    EXPECT_EQ(a.size(), b.size());
    double num = 0, den = 0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
        EXPECT_TRUE(std::isfinite(a[i])) << "element " << i;
        num += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
        den += b[i] * b[i];
    }
    return den > 0 ? std::sqrt(num / den) : std::sqrt(num);
}

} // namespace splatwarp::test
