#pragma once
/// @file FromVdb.h
/// @brief Volumes to splats (`from-vdb`; measurements: docs/lab/from-vdb.md): moment initialisation,
///        the Stage II engine as the fitter, the held-out error against the volume, and the
///        side-by-side render. No OpenVDB types (the volume is read by vdb/Volume.h).
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "vdb/Volume.h"
#include "core/GaussianCloud.h"
#include "field/FieldError.h"
#include "fit/MomentInit.h"
#include "fit/VolumeFit.h"
#include "image/Image.h"
#include "render/Camera.h"
#include "render/Rasterizer.h"

namespace splatwarp {

/// @brief What a fog value means (`--as`).
enum class VolumeMeaning {
    Auto,      ///< Field for our own `to-vdb` files, Extinction for any other fog volume
    Field,     ///< the value IS the splat opacity field O = sum alpha G (round trip closes)
    Extinction ///< the value is an extinction coefficient per world unit (Houdini/Blender smoke)
};

/// @brief Parse "auto", "field" or "extinction". @throws InputError otherwise
VolumeMeaning parseVolumeMeaning(const std::string& name);
/// @brief Auto resolved for a volume.
VolumeMeaning resolveMeaning(VolumeMeaning meaning, const Volume& volume);

/// @brief The held-out yardstick of a volume (depends on the volume and these options only).
struct VolumeJudgeOptions {
    std::size_t points = 100000; ///< random world points in the active voxels and the band
    std::uint32_t seed = 1;
    int band = 2;                ///< voxels outside the active region that count (leakage)
};

/// @brief Held-out points with the volume's values there, divided by the density scale.
struct VolumeJudge {
    std::vector<float> points;  ///< [P,3]
    FieldErrorTarget target;    ///< trilinear O (and F) of the volume / densityScale
    FeatureOptions features;    ///< the judged model's filter: the grid's own (our files) or none
};

/// @brief Fog value per unit of fitted opacity: 1 for Field, a quarter of the grid's maximum for
///        Extinction (opacities stay in (0, 1) while fitting; overlapping splats reach the peaks).
double densityScale(VolumeMeaning resolved, const Volume& volume);

/// @brief Draw the held-out points and look the volume up there (trilinear).
VolumeJudge makeVolumeJudge(const Volume& volume, double densityScale, const VolumeJudgeOptions& options = {});

/// @brief Relative L1 error of a model fitted in units of the density scale (opacity = O / scale).
FieldErrorReport judgeModel(const VolumeJudge& judge, const GaussianCloud& model);

/// @brief Options of fromVdb().
struct FromVdbOptions {
    VolumeMeaning meaning = VolumeMeaning::Auto;
    std::size_t gaussians = 0;  ///< budget; 0: one per 8 active voxels
    bool fit = true;            ///< false: stop after the moment initialisation (`--no-fit`)
    int band = 2;               ///< empty voxels around the active ones that train (boundary term) and judge
    /// Training samples per voxel along each axis. The volume means its trilinear field: with one
    /// sample per voxel the fit matches the voxel centres and drifts between them (wdas cloud, 30
    /// iterations: training energy / 4, held-out error 0.189 -> 0.184 only).
    int samplesPerAxis = 2;
    MomentInitOptions init;     ///< gaussians is overridden by the budget and the split reserve
    /// init.spread when not set (<= 0): 1.5 for Extinction, 1.0 for Field. Measured --no-fit errors:
    /// wdas cloud (1/8 per voxel) 0.286 at 1.0, 0.192 at 1.5, 0.171 at 1.8; the `ring` sample's
    /// to-vdb field 0.720 at 1.0, 0.819 at 1.5 (its splats are thin and already overlap).
    double spread = 0.0;
    /// Extinction per unit of fitted opacity; <= 0: densityScale(). Values below cutoff * scale
    /// cannot be represented, so a smaller scale keeps thin smoke.
    double densityScale = 0.0;
    VolumeFitOptions fitting;   ///< the engine (device, iterations, rounds, Stage II options)
    VolumeJudgeOptions judge;
    /// `--max-memory`: the fit's samples and Stage II's pair lists are refused past it before they
    /// are allocated; 0: no limit.
    std::size_t maxMemoryBytes = 0;
};

/// @brief The least a fit needs per active voxel (its samples at degree 0, without the band; with
///        --no-fit the voxels' copy): readVolume()'s check before the grid is read
///        (VolumeReadOptions::bytesPerVoxel).
std::uint64_t fitBytesPerVoxel(const FromVdbOptions& options);

/// @brief The defaults of a from-vdb fit (Stage II options tuned for fitting from scratch).
FromVdbOptions defaultFromVdbOptions();

/// @brief The result: splats ready to write (extinction already converted to opacity) and the report.
struct FromVdbResult {
    GaussianCloud splats;
    nlohmann::json report; ///< input, meaning, counts, iterations, times, held-out errors
};

/// @brief Initialise (and fit) Gaussians to a volume.
FromVdbResult fromVdb(const Volume& volume, const FromVdbOptions& options);

/// @brief The splats (left) beside a ray-marched render of the volume (right) from one camera,
///        labelled. Extinction volumes march their values; Field volumes march
///        O / (sqrt(2 pi) s) with s the splats' median geometric-mean scale (the extinction whose
///        centre-ray transmittance a splat of that size would have). The splats render with
///        renderGaussiansOn(splats, camera, render).
Image renderVolumeComparison(const Volume& volume, VolumeMeaning resolved, const GaussianCloud& splats,
                             const Camera& camera, const RenderOptions& render = {});

} // namespace splatwarp
