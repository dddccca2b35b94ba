#pragma once
/// @file VdbFileReader.h
/// @brief Read any `.vdb` file into plain arrays, for the tests' round trips (the library itself
///        only writes VDB files and reads fog volumes through vdb/Volume.h).
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace splatwarp::test {

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

/// @brief Rewrite a `.vdb` file with one float file-metadata entry set (hand-edited files).
void setFileMetadata(const std::string& path, const std::string& key, float value);
/// @brief The same with an int32 entry (e.g. our own "sh_degree").
void setFileMetadataInt(const std::string& path, const std::string& key, std::int32_t value);

/// @brief Read a `.vdb` file (float, double, int32, vec3s, bool and mask grids keep values).
/// @throws IoError naming the file when it cannot be opened or parsed.
VdbFileData readVdbFile(const std::string& path);

} // namespace splatwarp::test
