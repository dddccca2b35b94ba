#pragma once
/// @file SlabVolume.h
/// @brief The uniform extinction slab the from-vdb and ray-marcher tests look through: 32 x 32 x 10
///        voxels of edge kSlabVoxel, extinction kSlabSigma per world unit (sigma L = 1: exp(-1)
///        straight through along z; the trilinear ramps at the faces add up to whole voxels).
#include <cstddef>

#include "vdb/Volume.h"
#include "core/SmallMath.h"
#include "support/TestSupport.h"

namespace splatwarp::test {

constexpr double kSlabVoxel = 0.05, kSlabSigma = 2.0;
constexpr int kSlabSide = 32, kSlabThickness = 10; // voxels along x and y, and along z

/// @brief The slab's centre (voxel (i,j,k) is centred at kSlabVoxel * (i,j,k)).
inline Vec3d slabCentre() { return Vec3d(15.5 * kSlabVoxel, 15.5 * kSlabVoxel, 4.5 * kSlabVoxel); }

/// @brief The slab written to DIR/slab.vdb and read back.
inline Volume slabVolume(const TempDir& dir)
{
    DenseGrid d;
    d.voxelSize = kSlabVoxel;
    d.dims[0] = d.dims[1] = kSlabSide;
    d.dims[2] = kSlabThickness;
    d.values.assign(std::size_t(kSlabSide * kSlabSide * kSlabThickness), float(kSlabSigma));
    writeDenseGrids(dir.file("slab.vdb"), {d});
    return readVolume(dir.file("slab.vdb"));
}

} // namespace splatwarp::test
