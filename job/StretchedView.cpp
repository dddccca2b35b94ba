#include "job/StretchedView.h"

#include <algorithm>
#include <cmath>

#include "core/Polar.h"
#include "field/RigidMotion.h"
#include "render/Camera.h"
#include "render/ComparisonSheet.h"

namespace splatwarp {
namespace {

/// Largest target opacity and the rest and warped centres of a cell's samples.
struct CellSamples {
    float maxTarget = 0;
    Vec3d rest, warped;
};

CellSamples cellSamples(const SampleSet& s, std::size_t c)
{
    CellSamples out;
    const std::size_t first = s.firstSampleOf(c), last = s.firstSampleOf(c + 1);
    for (std::size_t j = first; j < last; ++j) {
        out.maxTarget = std::max(out.maxTarget, s.targetO[j]);
        for (int a = 0; a < 3; ++a) {
            out.rest[a] += s.restPositions[3 * j + std::size_t(a)];
            out.warped[a] += s.warpedPositions[3 * j + std::size_t(a)];
        }
    }
    const double n = double(std::max<std::size_t>(last - first, 1));
    out.rest = out.rest * (1.0 / n);
    out.warped = out.warped * (1.0 / n);
    return out;
}

/// The Gaussians of a cloud whose centres lie within radius of a point.
GaussianCloud cropped(const GaussianCloud& cloud, const Vec3d& centre, double radius)
{
    GaussianCloud out;
    out.resize(0, cloud.shDegree);
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        const Vec3d p(cloud.means[3 * i], cloud.means[3 * i + 1], cloud.means[3 * i + 2]);
        if (length(p - centre) <= radius) out.append(cloud, i);
    }
    return out;
}

/// Two views of a ball, each looking across the stretch axis, which lies horizontal in the image.
std::vector<Camera> closeUpCameras(const StretchedRegion& region, int size)
{
    const double fov = 40.0, distance = 1.1 * region.radius / std::sin(radians(fov / 2));
    const Vec3d u = region.stretchAxis;
    Vec3d a = std::abs(u.x) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
    a = a - u * dot(a, u);
    a = a * (1.0 / length(a));
    const Vec3d b = cross(u, a);
    std::vector<Camera> cameras;
    for (const Vec3d& view : {a, b}) {
        const Vec3d up = cross(view, u); // perpendicular to the stretch axis and the view
        cameras.push_back(Camera::lookAt(region.warpedCentre + view * distance, region.warpedCentre, up, fov, size, size));
    }
    return cameras;
}

} // namespace

std::optional<StretchedRegion> mostStretchedRegion(const SampleSet& warped, float minTarget)
{
    std::optional<StretchedRegion> best;
    for (std::size_t c = 0; c < warped.cellCount(); ++c) {
        if (warped.cellSkip[c]) continue;
        const Mat3d f = Mat3d::fromRowMajor(&warped.cellGradient[9 * c]);
        Vec3d lambda;
        Mat3d v;
        symmetricEigen3(f * f.transposed(), lambda, v); // F F^T: its eigenvectors are warped directions
        const double stretch = std::sqrt(std::max(lambda.x, 0.0));
        if (best && !(stretch > best->stretch)) continue;
        const CellSamples s = cellSamples(warped, c);
        if (s.maxTarget < minTarget) continue;
        StretchedRegion r;
        r.cell = c;
        r.stretch = stretch;
        r.stretchAxis = Vec3d(v[0][0], v[1][0], v[2][0]);
        r.restCentre = s.rest;
        r.warpedCentre = s.warped;
        r.rotation = polarRotation(f);
        r.radius = 1.5 * double(warped.cellSize) * std::max(stretch, 1.0);
        best = r;
    }
    return best;
}

Image renderStretchedCloseUp(const GaussianCloud& rest, const GaussianCloud& stage1, const GaussianCloud& stage2,
                             const StretchedRegion& region, int size, const RenderOptions& render)
{
    const GaussianCloud moved =
        rigidlyMoved(rest, region.rotation, region.warpedCentre - region.rotation * region.restCentre);
    const GaussianCloud a = cropped(moved, region.warpedCentre, region.radius);
    const GaussianCloud b = cropped(stage1, region.warpedCentre, region.radius);
    const GaussianCloud c = cropped(stage2, region.warpedCentre, region.radius);
    ComparisonSheetOptions options;
    options.render = render;
    return renderComparisonSheet({&a, &b, &c}, {"rest, moved rigidly", "stage I", "stage II"},
                                 closeUpCameras(region, size), options);
}

} // namespace splatwarp
