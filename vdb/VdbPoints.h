#pragma once
/// @file VdbPoints.h
/// @brief Gaussian models as OpenVDB point grids (a PointDataGrid named "splats"), with the
///        attributes of Houdini 21's GSplat SOPs: P, orient (quaternion), scale (linear), Cd
///        (0.5 + C0 f_dc), GS_Alpha (opacity after the sigmoid), GS_SPH_R/G/B (the raw SH
///        coefficients of each channel, DC first), plus id (the index in the source model, so a read
///        restores the order the grid's voxel sort changed). See docs/formats.md.
#include <string>

#include "core/GaussianCloud.h"
#include "io/GaussianIO.h"

namespace splatwarp {

/// @brief Write a cloud as a `.vdb` point grid (atomically). Positions keep float32 precision.
/// @throws InputError for NaN/Inf values or an empty cloud.
void writeVdbPoints(const std::string& path, const GaussianCloud& cloud);

/// @brief Read the first PointDataGrid of a `.vdb` held in memory; `name` names it in messages.
/// @throws InputError when the bytes are not a readable VDB, hold no point grid, or lack P, scale
///         (or pscale) or GS_Alpha.
GaussianCloud readVdbPoints(const std::string& name, const std::string& data, ReadReport& report);

/// @brief Make readGaussians() accept `.vdb` point grids and writeGaussians() write them for
///        paths ending in ".vdb" (src/io cannot include OpenVDB). Idempotent; the CLI calls it
///        at start-up, library users once before reading.
void registerVdbPointFormat();

} // namespace splatwarp
