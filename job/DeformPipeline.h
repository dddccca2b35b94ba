#pragma once
/// @file DeformPipeline.h
/// @brief One `deform` run as a library call: read, Stage I, SampleGrid + warp, Stage II, held-out
///        field errors, outputs (baseline.ply, deformed.ply, report.json, field.vdb, compare.png).
///        Lives in job/ (above vdb/, whose SampleGrid it drives); the CLI only parses flags into it.
#include <cstdint>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "HeldOutEval.h"
#include "SampleGrid.h"
#include "core/Device.h"
#include "deform/StageOne.h"
#include "stage2/StageTwoOptions.h"

namespace splatwarp {

/// @brief Everything a deform run needs; defaults are those of each stage's options struct.
struct DeformJobOptions {
    std::string input;     ///< model to deform (any supported format)
    std::string specPath;  ///< deformation spec JSON
    std::string outDir;    ///< created if missing
    bool stage1Only = false;           ///< stop after Stage I (baseline.ply only)
    std::optional<int> nodes, k;       ///< override the spec's graph block
    std::optional<std::uint32_t> seed;
    EdOptions ed;
    StageOneOptions stage1;
    SampleGridOptions grid;
    StageTwoOptions stage2;
    HeldOutOptions heldOut;
    bool evaluate = true;   ///< held-out field errors of Stage I and Stage II in the report
    int evalEvery = 0;      ///< also record the held-out error every K Stage II iterations (0 = off)
    bool writeVdb = false;  ///< field.vdb: the Stage II model's field (same grids as `to-vdb`)
    bool render = false;    ///< compare.png: rest | Stage I | Stage II from a few orbit views
    int renderViews = 3;    ///< orbit views in compare.png
    int renderSize = 320;   ///< pixels per view (square)
    Device device = Device::Auto; ///< where the Stage I update and Stage II run (auto: CUDA when compiled in and a GPU is present)
};

/// @brief Run the job and write its outputs; returns the report that was written to report.json.
/// @throws InputError / IoError with a message naming the file and the problem.
nlohmann::json runDeformJob(const DeformJobOptions& options);

} // namespace splatwarp
