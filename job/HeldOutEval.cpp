#include "job/HeldOutEval.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "core/Error.h"
#include "deform/WarpDevice.h"
#include "field/PreparedGaussian.h"
#include "sh/SphericalHarmonics.h"
#include "stage2/BlockFeatures.h"

namespace splatwarp {

namespace {

/// Points uniform over equal-volume cells: a uniform cell then a uniform offset. Continuous
/// offsets never coincide with a training lattice.
HeldOutPoints drawInCells(const std::int32_t* cells, std::size_t cellCount, const std::int64_t origin[3], double h,
                          const HeldOutOptions& options)
{
    if (cellCount == 0 || options.points == 0) throw InputError("held-out evaluation needs active cells and points > 0");
    HeldOutPoints out;
    out.rest.resize(3 * options.points);
    std::mt19937_64 rng(options.seed);
    std::uniform_int_distribution<std::size_t> pickCell(0, cellCount - 1);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (std::size_t p = 0; p < options.points; ++p) {
        const std::size_t c = pickCell(rng);
        for (int a = 0; a < 3; ++a)
            out.rest[3 * p + a] = float((double(origin[a] + cells[3 * c + a]) + unit(rng)) * h);
    }
    out.warped = out.rest;
    out.rotations.assign(3 * out.rest.size(), 0.0f);
    for (std::size_t p = 0; p < options.points; ++p)
        for (int a = 0; a < 3; ++a) out.rotations[9 * p + std::size_t(4 * a)] = 1.0f;
    return out;
}

/// Union of the Gaussians' boxes in world space (those that reach the cutoff).
void unionBox(const std::vector<PreparedGaussian>& gaussians, Vec3d& lo, Vec3d& hi)
{
    lo = Vec3d(std::numeric_limits<double>::max(), std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
    hi = -lo;
    for (const PreparedGaussian& g : gaussians) {
        if (g.radius2 < 0.0f) continue;
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], double(g.mean[k]) - double(g.halfExtent[k]));
            hi[k] = std::max(hi[k], double(g.mean[k]) + double(g.halfExtent[k]));
        }
    }
}

/// Dense cell counts of a small lattice (at most ~(kJudgeRegionCells + 4)^3 cells).
struct CellMask {
    std::int64_t dims[3] = {0, 0, 0};
    std::vector<std::int32_t> count;

    std::size_t at(std::int64_t x, std::int64_t y, std::int64_t z) const { return std::size_t((x * dims[1] + y) * dims[2] + z); }
    /// body(cell, {x, y, z}, step) over every cell in x-major order (step: index strides per axis).
    template <typename Body>
    void forEach(const Body& body)
    {
        const std::int64_t step[3] = {dims[1] * dims[2], dims[2], 1};
        for (std::int64_t x = 0; x < dims[0]; ++x)
            for (std::int64_t y = 0; y < dims[1]; ++y)
                for (std::int64_t z = 0; z < dims[2]; ++z) {
                    const std::int64_t i[3] = {x, y, z};
                    body(at(x, y, z), i, step);
                }
    }
    /// Turn +1 / -1 box corners into per-cell box counts (a prefix sum along each axis; x-major
    /// order visits the previous cell along any axis first).
    void prefixSums()
    {
        for (int axis = 0; axis < 3; ++axis)
            forEach([&](std::size_t c, const std::int64_t* i, const std::int64_t* step) {
                if (i[axis] > 0) count[c] += count[c - std::size_t(step[axis])];
            });
    }
    /// Mark every cell next to a covered one (26 neighbours): a 3-wide max along each axis.
    void dilate()
    {
        for (std::int32_t& c : count) c = c > 0 ? 1 : 0;
        for (int axis = 0; axis < 3; ++axis) {
            const std::vector<std::int32_t> before = count;
            forEach([&](std::size_t c, const std::int64_t* i, const std::int64_t* step) {
                if (i[axis] > 0) count[c] |= before[c - std::size_t(step[axis])];
                if (i[axis] + 1 < dims[axis]) count[c] |= before[c + std::size_t(step[axis])];
            });
        }
    }
};

} // namespace

FeatureOptions judgeFeatureOptions()
{
    FeatureOptions f;
    f.cutoff = kDefaultCutoff;
    f.filterVariance = 0.0f;
    return f;
}

JudgeRegion judgeRegion(const GaussianCloud& rest, bool threaded)
{
    const FeatureOptions f = judgeFeatureOptions();
    const std::vector<PreparedGaussian> gaussians = prepareCloud(rest, f.filterVariance, f.cutoff, threaded);
    Vec3d lo, hi;
    unionBox(gaussians, lo, hi);
    if (!(lo.x <= hi.x)) throw InputError("judge: no Gaussian of the rest model reaches the cutoff 1/255");
    const double extent = std::max(hi.x - lo.x, std::max(hi.y - lo.y, hi.z - lo.z));
    if (!(extent > 0.0) || !std::isfinite(extent)) throw InputError("judge: the rest model has zero extent");
    JudgeRegion region;
    region.cellSize = extent / kJudgeRegionCells;
    const double h = region.cellSize;
    CellMask mask;
    // One cell of margin on each side for the band, one more for the boxes' exclusive ends.
    for (int k = 0; k < 3; ++k) {
        region.origin[k] = std::int64_t(std::floor(lo[k] / h)) - 1;
        mask.dims[k] = std::int64_t(std::floor(hi[k] / h)) + 3 - region.origin[k];
    }
    mask.count.assign(std::size_t(mask.dims[0] * mask.dims[1] * mask.dims[2]), 0);
    for (const PreparedGaussian& g : gaussians) {
        if (g.radius2 < 0.0f) continue;
        std::int64_t b[2][3];
        for (int k = 0; k < 3; ++k) {
            b[0][k] = std::int64_t(std::floor((double(g.mean[k]) - double(g.halfExtent[k])) / h)) - region.origin[k];
            b[1][k] = std::int64_t(std::floor((double(g.mean[k]) + double(g.halfExtent[k])) / h)) - region.origin[k] + 1;
        }
        for (int corner = 0; corner < 8; ++corner) {
            const int ex = corner & 1, ey = (corner >> 1) & 1, ez = (corner >> 2) & 1;
            mask.count[mask.at(b[ex][0], b[ey][1], b[ez][2])] += (ex + ey + ez) % 2 ? -1 : 1;
        }
    }
    mask.prefixSums();
    mask.dilate();
    mask.forEach([&](std::size_t c, const std::int64_t* i, const std::int64_t*) {
        if (mask.count[c]) region.cells.insert(region.cells.end(), {std::int32_t(i[0]), std::int32_t(i[1]), std::int32_t(i[2])});
    });
    return region;
}

HeldOutPoints drawJudgePoints(const GaussianCloud& rest, const HeldOutOptions& options)
{
    return drawJudgePoints(judgeRegion(rest), options);
}

HeldOutPoints drawJudgePoints(const JudgeRegion& region, const HeldOutOptions& options)
{
    HeldOutPoints out = drawInCells(region.cells.data(), region.size(), region.origin, region.cellSize, options);
    out.features = judgeFeatureOptions();
    out.features.device = options.device;
    return out;
}

HeldOutPoints drawHeldOutPoints(const SampleGrid& grid, const HeldOutOptions& options)
{
    const std::int64_t origin[3] = {0, 0, 0};
    HeldOutPoints out = drawInCells(grid.cellCoords().data(), grid.cellCoords().size() / 3, origin,
                                    grid.samples().cellSize, options);
    out.features = grid.targetOptions(); // the very cutoff and filter the rest targets used
    out.features.device = options.device;
    return out;
}

void warpHeldOutPoints(HeldOutPoints& points, const Deformation& deformation, bool threaded)
{
    warpPointsOn(deformation.graph, deformation.transforms, points.rest.data(), points.size(), points.warped.data(),
                 points.rotations.data(), {points.features.device, threaded});
}

HeldOutPoints makeHeldOutPoints(const SampleGrid& grid, const Deformation& deformation, const HeldOutOptions& options)
{
    HeldOutPoints out = drawHeldOutPoints(grid, options);
    warpHeldOutPoints(out, deformation, grid.options().threaded);
    return out;
}

namespace {

/// The rest side at the points' rest positions on the block engine (the same bits as
/// fieldErrorTarget()'s per-point evaluation), SH rotated by `rotations` when given.
FieldErrorTarget restTarget(const GaussianCloud& rest, const HeldOutPoints& points, const float* rotations)
{
    std::vector<float> f(points.size() * std::size_t(rest.shStride())), o(points.size());
    evaluatePointsOn(rest, points.rest.data(), points.size(), points.features, f.data(), o.data());
    return fieldErrorTarget(rest, f.data(), std::move(o), rotations);
}

} // namespace

FieldErrorTarget unrotatedTarget(const GaussianCloud& rest, const HeldOutPoints& points)
{
    return restTarget(rest, points, nullptr);
}

FieldErrorTarget rotatedTarget(const FieldErrorTarget& unrotated, const HeldOutPoints& points)
{
    FieldErrorTarget t = unrotated;
    if (t.shDegree == 0) return t;
    const std::size_t stride = t.features.size() / std::max<std::size_t>(t.size(), 1);
    for (std::size_t j = 0; j < t.size(); ++j) {
        Mat3d rot;
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) rot.m[a][b] = points.rotations[9 * j + std::size_t(3 * a + b)];
        ShRotation(rot, t.shDegree).apply(t.shDegree, t.features.data() + j * stride);
    }
    return t;
}


FieldErrorTarget heldOutTarget(const GaussianCloud& rest, const HeldOutPoints& points)
{
    return restTarget(rest, points, points.rotations.data());
}

FieldErrorReport evaluateHeldOut(const FieldErrorTarget& target, const GaussianCloud& deformed,
                                 const HeldOutPoints& points)
{
    return fieldErrorOf(target, heldOutPointErrors(target, deformed, points));
}

FieldPointErrors heldOutPointErrors(const FieldErrorTarget& target, const GaussianCloud& deformed,
                                    const HeldOutPoints& points)
{
    if (target.size() != points.size())
        throw InputError(msg("held-out evaluation: a rest side of ", target.size(), " points for ", points.size(), " points"));
    std::vector<float> f(points.size() * std::size_t(deformed.shStride())), o(points.size());
    evaluatePointsOn(deformed, points.warped.data(), points.size(), points.features, f.data(), o.data());
    return fieldPointErrors(target, deformed, f.data(), o.data());
}

FieldErrorReport evaluateHeldOut(const GaussianCloud& rest, const GaussianCloud& deformed, const HeldOutPoints& points)
{
    return fieldError(rest, deformed, points.rest.data(), points.warped.data(), points.rotations.data(), points.size(),
                      points.features);
}

nlohmann::json fieldErrorJson(const FieldErrorReport& r)
{
    return {{"opacity", r.opacity},
            {"color", r.color},
            {"points", r.points},
            {"inside", {{"opacity", r.opacityInside}, {"color", r.colorInside}, {"points", r.insidePoints}}},
            {"outside", {{"opacity", r.opacityOutside}, {"color", r.colorOutside}, {"points", r.outsidePoints}}}};
}

} // namespace splatwarp
