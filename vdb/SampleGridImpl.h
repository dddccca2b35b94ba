#pragma once
/// @file SampleGridImpl.h
/// @brief The OpenVDB side of SampleGrid, shared by the vdb/ translation units only (it includes
///        OpenVDB; never include it from src/, tools/ or tests/).
#include <openvdb/openvdb.h>

#include "vdb/SampleGrid.h"

namespace splatwarp {

struct SampleGrid::Impl {
    SampleGridOptions options;
    SampleGridStats stats;
    SampleSet set;
    FeatureOptions targetOptions; ///< of the rest targets
    std::vector<std::int32_t> gaussianCell; ///< [N]
    std::vector<std::int32_t> cellCoords;   ///< [C,3]
    /// Cell index per active cell (background -1); transform: voxel size h, cell (i,j,k)
    /// spanning [i h, (i+1) h).
    openvdb::Int32Grid::Ptr index;

    /// Integer cell coordinate floor(x / h) along one axis.
    int cellCoordOf(double x) const;
    openvdb::Coord cellOf(const Vec3d& p) const;
    /// Fill set.cellSkip (and stats.skippedCells) from the targets.
    void computeCellSkip();
};

} // namespace splatwarp
