#pragma once
/// @file Volume.h
/// @brief A fog volume read from a `.vdb` file (the input of `from-vdb` and `eval --volume`):
///        a FloatGrid (level sets converted to fog) with optional colour or `sh_<k>` grids,
///        seen through plain arrays and trilinear lookups, never OpenVDB types.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/SmallMath.h"
#include "field/SampleSet.h"
#include "fit/MomentInit.h"

namespace splatwarp {

/// @brief Which grids readVolume() takes.
struct VolumeReadOptions {
    std::string grid;      ///< FloatGrid to fit; "" = `density`, else the file's only FloatGrid
    std::string colorGrid; ///< Vec3 colour grid; "" = `color` or `Cd` when present; "none" = ignore colour
    /// Refuse grids whose fit would need more than this many bytes (bytesPerVoxel per active
    /// voxel), checked before the grid is read; 0 = the memory the system reports available.
    std::uint64_t memoryLimit = 0;
    /// What the fit needs at least per active voxel (from-vdb sets it from its samples per voxel;
    /// the default is its own at 2: 8 samples of a degree-0 field).
    std::uint64_t bytesPerVoxel = 1024;
};

/// @brief What was read.
struct VolumeInfo {
    std::string path;
    std::string grid;        ///< name of the density grid
    std::string colorGrid;   ///< "" when none; "sh_*" for our own SH grids
    int shDegree = 0;        ///< degree of the features (0 without SH grids)
    bool ownFile = false;    ///< written by `splatwarp to-vdb` (creator metadata)
    bool levelSet = false;   ///< converted from a level set
    float lambdaLpf = 0.0f;  ///< our files: the targets' rest filter strength (variance lambda s^2)
    double voxelSize = 0.0;
    std::size_t activeVoxels = 0;
    float minValue = 0.0f, maxValue = 0.0f;
    std::vector<std::string> notes; ///< conversions and defaults worth telling the user
    /// The isotropic filter variance the values hold: our files' rest filter lambda s^2 (s the
    /// voxel, = the sample spacing), 0 for other volumes.
    double restFilterVariance() const { return ownFile ? double(lambdaLpf) * voxelSize * voxelSize : 0.0; }
};

/// @brief A volume in memory (OpenVDB grids behind a pimpl).
class Volume {
public:
    ~Volume();
    Volume(Volume&&) noexcept;
    Volume& operator=(Volume&&) noexcept;

    const VolumeInfo& info() const;
    /// @brief Floats of features per point: 3 (shDegree+1)^2.
    int featureStride() const;
    /// @brief Trilinear density (and features F, [m, stride], may be null) at world points [m,3].
    void sample(const float* points, std::size_t m, float* density, float* features) const;
    /// @brief The active voxels (centres, values, features) for the moment initialisation.
    VoxelSamples activeVoxels() const;
    /// @brief Samples for the Stage II engine: a sub-lattice of perAxis^3 points per voxel (offsets
    ///        (a + 1/2)/perAxis - 1/2 voxels) in every active voxel and every voxel within `band`
    ///        voxels of one, targets = the trilinear field there (= the voxel values at perAxis 1);
    ///        cells = 2^3-voxel blocks (samples of a cell consecutive), identity gradients, none skipped.
    SampleSet sampleSet(int band, int perAxis = 1) const;
    /// @brief How many samples sampleSet(band, perAxis) holds, counted without building it.
    std::size_t sampleCount(int band, int perAxis = 1) const;
    /// @brief Held-out points: uniform in the voxels of sampleSet(band) (continuous positions).
    std::vector<float> heldOutPoints(std::size_t count, std::uint32_t seed, int band) const;
    /// @brief World bounds of the trilinear field: the active voxels' centres plus one voxel (the
    ///        interpolation ramps to zero at the next, inactive voxel centre, half a voxel beyond
    ///        the voxel boxes).
    void worldBounds(Vec3d& lo, Vec3d& hi) const;

    struct Impl;
    explicit Volume(std::unique_ptr<Impl> impl);

private:
    std::unique_ptr<Impl> mImpl;
};

/// @brief Read a fog volume.
/// @throws InputError naming the file (and grid) for a file that is not a VDB, no float grid or
///         an ambiguous choice (the message lists the grids), an empty grid, NaN/Inf values, a
///         non-uniform or non-linear transform, or a grid too large for memory.
Volume readVolume(const std::string& path, const VolumeReadOptions& options = {});

} // namespace splatwarp

namespace splatwarp {

/// @brief A dense block of voxel values to write as a grid (tests, examples, studies).
struct DenseGrid {
    std::string name = "density";
    int origin[3] = {0, 0, 0};  ///< index of the first voxel
    int dims[3] = {0, 0, 0};    ///< voxels along x, y, z (x fastest in values)
    double voxelSize = 1.0;     ///< voxel (i,j,k) is centred at voxelSize * (i,j,k)
    std::vector<float> values;  ///< [dims z][y][x]; zeros stay inactive
    bool vector = false;        ///< write a Vec3SGrid (value in every channel) instead of a FloatGrid
    bool levelSet = false;      ///< grid class level set instead of fog volume
    /// When fillVoxels > 0: an active tile box of this edge at the origin with value fillValue
    /// (sparse: costs nothing on disk; large volumes for memory checks).
    int fillVoxels = 0;
    float fillValue = 1.0f;
};

/// @brief Write grids to a `.vdb` (atomically).
void writeDenseGrids(const std::string& path, const std::vector<DenseGrid>& grids);

} // namespace splatwarp
