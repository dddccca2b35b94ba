#pragma once
/// @file VdbExport.h
/// @brief Write a SampleGrid as a `.vdb` file (grids and metadata below). The tests read files
///        back with tests/support/VdbFileReader.h.
#include <string>

#include "vdb/SampleGrid.h"

namespace splatwarp {

/// @brief What writeSampleGridVdb() writes besides `density`, `color` and `active`.
struct VdbExportOptions {
    bool shGrids = false;  ///< one Vec3SGrid `sh_<k>` per SH coefficient k of the target F
    bool half = false;     ///< store float grids as 16-bit half floats (smaller, ~3 digits)
    bool stretch = false;  ///< `stretch` FloatGrid per cell: largest singular value of F_k (warped grids)
    std::string source;    ///< source file recorded in the metadata
    std::string spec;      ///< deformation spec recorded in the metadata ("" = none)
    bool threaded = true;  ///< build the sample grids with oneTBB (the file is identical either way)
};

/// @brief Write the grids of a sample grid atomically, ZIP-compressed.
/// @details Sample grids (`density` fog volume of O, `color` = 0.5 + C0 F_dc / O where O > 0,
///          `sh_<k>`) have voxel size = sample spacing s and voxel centres exactly on the rest
///          sample positions (index I at (I + 1/2) s). `active` (BoolGrid, true at active cells) and `stretch` have voxel
///          size h with cell (i,j,k) centred at ((i + 1/2) h, ...). File and grid metadata:
///          source, sh_degree, cell_size, samples_per_axis, samples_per_cell, cutoff, lambda_lpf
///          (+ spec).
/// @throws IoError when the file cannot be written (no partial file is left).
void writeSampleGridVdb(const std::string& path, const SampleGrid& grid, const VdbExportOptions& options = {});

} // namespace splatwarp
