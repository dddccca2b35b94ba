// Volume::worldBounds holds the whole trilinear field, and the ray marcher that uses it
// (from-vdb --render) is exact on a uniform slab: the interpolation ramps down to zero one voxel
// past the outermost active voxel centres, half a voxel beyond their voxel boxes.
#include <gtest/gtest.h>

#include <cmath>

#include "vdb/Volume.h"
#include "render/RayMarcher.h"
#include "support/SlabVolume.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

TEST(VolumeBounds, HoldTheTrilinearRampPastTheActiveVoxels)
{
    const double s = 0.1;
    DenseGrid d;
    d.voxelSize = s;
    d.dims[0] = d.dims[1] = d.dims[2] = 1; // one voxel of value 1 at the origin
    d.values = {1.0f};
    test::TempDir dir;
    writeDenseGrids(dir.file("one.vdb"), {d});
    const Volume volume = readVolume(dir.file("one.vdb"));
    Vec3d lo, hi;
    volume.worldBounds(lo, hi);
    const float inside[3] = {float(0.9 * s), 0.0f, 0.0f}, outside[3] = {float(1.1 * s), 0.0f, 0.0f};
    float v = 0;
    volume.sample(inside, 1, &v, nullptr);
    EXPECT_NEAR(v, 0.1, 1e-5) << "the trilinear ramp reaches past the voxel's box";
    EXPECT_LT(lo.x, 0.9 * -s);
    EXPECT_GT(hi.x, 0.9 * s);
    volume.sample(outside, 1, &v, nullptr);
    EXPECT_EQ(v, 0.0f);
    for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(lo[a], -s, 1e-12);
        EXPECT_NEAR(hi[a], s, 1e-12);
    }
}

// The uniform slab (support/SlabVolume.h, sigma L = 1) seen straight through its centre.
TEST(VolumeBounds, RayMarchedSlabTransmitsExactly)
{
    const double s = test::kSlabVoxel, sigma = test::kSlabSigma;
    test::TempDir dir;
    const Volume volume = test::slabVolume(dir);
    const VolumeLookup lookup = [&](const float* p, std::size_t m, float* sig, float* rgb) {
        volume.sample(p, m, sig, nullptr);
        for (std::size_t k = 0; k < 3 * m; ++k) rgb[k] = 1.0f;
    };
    Vec3d lo, hi;
    volume.worldBounds(lo, hi);
    const Vec3d c = test::slabCentre();
    const Camera cam = Camera::lookAt(c + Vec3d(0, 0, 40.0), c, Vec3d(0, 1, 0), 0.5, 32, 32);
    RayMarchOptions o;
    o.step = 0.5 * s;
    const Image image = rayMarch(lookup, lo, hi, cam, o);
    const double transmittance = 1.0 - image.at(16, 16, 3);
    // Measured 0.377 with the bounds at the voxel boxes (the ramps cut); exact now up to float sums.
    EXPECT_NEAR(transmittance, std::exp(-sigma * test::kSlabThickness * s), 1e-4);
}

} // namespace
} // namespace splatwarp
