#include "field/RigidMotion.h"

#include "sh/SphericalHarmonics.h"

namespace splatwarp {

GaussianCloud rigidlyMoved(const GaussianCloud& cloud, const Mat3d& r, const Vec3d& t)
{
    GaussianCloud moved = cloud;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        moved.setMean(i, Vec3f(r * Vec3d(cloud.mean(i)) + t));
        const Quatd q{cloud.rotations[4 * i], cloud.rotations[4 * i + 1], cloud.rotations[4 * i + 2],
                      cloud.rotations[4 * i + 3]};
        const Quatd nq = matrixToQuat(r * quatToMatrix(q));
        moved.setRotation(i, Quatf{float(nq.w), float(nq.x), float(nq.y), float(nq.z)});
    }
    rotateCloudSh(moved, r);
    return moved;
}

} // namespace splatwarp
