#pragma once
/// @file VdbExport.h
/// @brief Write a SampleGrid as a `.vdb` file (DESIGN.md "Outputs"), and read any `.vdb` back
///        into plain arrays (round-trip tests, inspection) without OpenVDB types.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "SampleGrid.h"

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

/// @brief One grid of a `.vdb` file as plain arrays.
struct VdbGridData {
    std::string name;
    std::string valueType;  ///< OpenVDB type name: "float", "vec3s", "mask", ...
    std::string gridClass;  ///< "fog volume", "level set", "unknown", ...
    double voxelSize = 0.0; ///< uniform voxel size (x axis)
    double origin[3] = {0, 0, 0}; ///< world position of the centre of voxel (0,0,0)
    bool savedAsHalf = false;
    std::map<std::string, std::string> metadata; ///< grid metadata, values as strings
    std::vector<std::int32_t> coords;            ///< [V,3] active voxel coordinates
    std::vector<float> values;                   ///< [V,channels] (float: 1, vec3s: 3, mask/others: none)
    int channels = 0;
};

/// @brief File metadata and every grid of a `.vdb` file.
struct VdbFileData {
    std::map<std::string, std::string> metadata;
    std::vector<VdbGridData> grids;
    /// @brief The grid of a name, or nullptr.
    const VdbGridData* find(const std::string& name) const;
};

/// @brief Read a `.vdb` file (float, double, int32, vec3s, bool and mask grids keep values).
/// @throws IoError naming the file when it cannot be opened or parsed.
VdbFileData readVdbFile(const std::string& path);

} // namespace splatwarp
