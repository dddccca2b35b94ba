#include "HeldOutEval.h"

#include <random>

#include "core/Error.h"
#include "deform/WarpDevice.h"

namespace splatwarp {

HeldOutPoints makeHeldOutPoints(const SampleGrid& grid, const Deformation& deformation, const HeldOutOptions& options)
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
    out.warped.resize(out.rest.size());
    out.rotations.resize(3 * out.rest.size());
    warpPointsOn(options.device, deformation.graph, deformation.transforms, out.rest.data(), options.points,
                 out.warped.data(), out.rotations.data(), grid.options().threaded);
    out.features = grid.targetOptions(); // the very cutoff and filter the rest targets used
    return out;
}

namespace {
FeatureOptions onDevice(const HeldOutPoints& points, Device device)
{
    FeatureOptions options = points.features;
    options.device = device;
    return options;
}
} // namespace

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
