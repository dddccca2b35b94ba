#include "HeldOutEval.h"

#include <algorithm>
#include <random>

#include "core/Error.h"
#include "deform/WarpDevice.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {
FeatureOptions onDevice(const HeldOutPoints& points, Device device)
{
    FeatureOptions options = points.features;
    options.device = device;
    return options;
}
} // namespace

HeldOutPoints drawHeldOutPoints(const SampleGrid& grid, const HeldOutOptions& options)
{
    const std::vector<std::int32_t>& cells = grid.cellCoords();
    const std::size_t cellCount = cells.size() / 3;
    if (cellCount == 0 || options.points == 0) throw InputError("held-out evaluation needs active cells and points > 0");
    const double h = grid.samples().cellSize;
    HeldOutPoints out;
    out.rest.resize(3 * options.points);
    // Every cell has the same volume, so a uniform cell then a uniform offset is uniform over
    // the active region; continuous offsets never coincide with the training lattice.
    std::mt19937_64 rng(options.seed);
    std::uniform_int_distribution<std::size_t> pickCell(0, cellCount - 1);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (std::size_t p = 0; p < options.points; ++p) {
        const std::size_t c = pickCell(rng);
        for (int a = 0; a < 3; ++a) out.rest[3 * p + a] = float((cells[3 * c + a] + unit(rng)) * h);
    }
    out.warped = out.rest;
    out.rotations.assign(3 * out.rest.size(), 0.0f);
    for (std::size_t p = 0; p < options.points; ++p)
        for (int a = 0; a < 3; ++a) out.rotations[9 * p + std::size_t(4 * a)] = 1.0f;
    out.features = grid.targetOptions(); // the very cutoff and filter the rest targets used
    return out;
}

void warpHeldOutPoints(HeldOutPoints& points, const Deformation& deformation, Device device, bool threaded)
{
    warpPointsOn(device, deformation.graph, deformation.transforms, points.rest.data(), points.size(),
                 points.warped.data(), points.rotations.data(), threaded);
}

HeldOutPoints makeHeldOutPoints(const SampleGrid& grid, const Deformation& deformation, const HeldOutOptions& options)
{
    HeldOutPoints out = drawHeldOutPoints(grid, options);
    warpHeldOutPoints(out, deformation, options.device, grid.options().threaded);
    return out;
}

FieldErrorTarget unrotatedTarget(const GaussianCloud& rest, const HeldOutPoints& points, Device device)
{
    return fieldErrorTarget(rest, points.rest.data(), nullptr, points.size(), onDevice(points, device));
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


FieldErrorTarget heldOutTarget(const GaussianCloud& rest, const HeldOutPoints& points, Device device)
{
    return fieldErrorTarget(rest, points.rest.data(), points.rotations.data(), points.size(), onDevice(points, device));
}

FieldErrorReport evaluateHeldOut(const FieldErrorTarget& target, const GaussianCloud& deformed,
                                 const HeldOutPoints& points, Device device)
{
    if (target.size() != points.size())
        throw InputError(msg("held-out evaluation: a rest side of ", target.size(), " points for ", points.size(), " points"));
    return fieldError(target, deformed, points.warped.data(), onDevice(points, device));
}

FieldErrorReport evaluateHeldOut(const GaussianCloud& rest, const GaussianCloud& deformed, const HeldOutPoints& points,
                                 Device device)
{
    return fieldError(rest, deformed, points.rest.data(), points.warped.data(), points.rotations.data(), points.size(),
                      onDevice(points, device));
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
