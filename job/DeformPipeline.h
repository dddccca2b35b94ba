#pragma once
/// @file DeformPipeline.h
/// @brief One `deform` run as a library call: read, Stage I, SampleGrid + warp, Stage II, held-out
///        field errors, outputs (baseline.ply, deformed.ply, report.json, field.vdb, compare.png).
///        Split into a rest side computed once (DeformRest) and a per-spec part (runDeformFrame)
///        so an animation reuses the rest side for every frame with the bytes of `deform`.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "job/FrameReport.h"
#include "job/StretchedView.h"
#include "job/Judge.h"
#include "vdb/SampleGrid.h"
#include "core/Device.h"
#include "core/GaussianBudget.h"
#include "deform/CurveSplit.h"
#include "deform/DeformSpec.h"
#include "deform/Deformation.h"
#include "deform/StageOne.h"
#include "deform/StageOneDevice.h"
#include "io/GaussianIO.h"
#include "job/StageTwoRounds.h"
#include "stage2/StageTwo.h"
#include "stage2/StageTwoOptions.h"

namespace splatwarp {

/// @brief Everything a deform run needs; defaults are those of each stage's options struct (the
///        CLI's are deformDefaults(), job/DeformSettings.h, whose table sets and records each one).
struct DeformJobOptions {
    std::string input;     ///< model to deform (any supported format)
    std::string specPath;  ///< deformation spec JSON
    std::string recipePath; ///< the recipe file the settings came from (an input: never written), "" for a built-in
    std::string outDir;    ///< created if missing
    bool stage1Only = false;           ///< stop after Stage I (baseline.ply only; runDeformJob removes an earlier run's deformed.ply, field.vdb, compare.png)
    bool dropInvalid = false;          ///< drop unusable Gaussians of the input instead of refusing it
    std::optional<int> nodes, k;       ///< override the spec's graph block
    std::optional<std::uint32_t> seed;
    EdOptions ed;
    StageOneOptions stage1;
    SampleGridOptions grid;   ///< grid.fineBelow: the fine-cell threshold in use (0: no fine cells)
    float fineCellsBelow = 4.0f; ///< the threshold --fine-cells auto puts in grid.fineBelow (--fine-below)
    StageTwoOptions stage2;
    DensifyJobOptions densify;
    bool curveSplit = true;    ///< split the Gaussians Stage I cannot bend before Stage II (deform/CurveSplit.h)
    /// The most Gaussians the output may hold (nullopt: none, the curve split's maxAdded bounds its
    /// and the validated split's additions, Stage II's split is unbounded). With budgetMerge it is met
    /// after the keep; else every step that adds Gaussians (curve split, validated split, Stage II's
    /// split) spends from it in that order. 1.5x: the field judge within 10% of no budget (2.25x) on
    /// every capture row, the image judge level on average (docs/lab/gaussian-budget.md).
    std::optional<GaussianBudget> maxGaussians = GaussianBudget{1.5, 0};
    /// With a budget and the keep: the splits before Stage II add their own share and, after the
    /// keep, the families of children that buy least are merged back until the model fits it
    /// (job/BudgetMerge.h); off: the splits spend the budget itself.
    bool budgetMerge = true;
    CurveSplitOptions curve;
    /// With --keep validated, the start with its means moved by this share of phi's second-order
    /// offset is one more candidate (deform/CurveSplit.h curveShifted()); nullopt: the share of
    /// kCurveShares the validation points judge best; 0: no such candidate.
    std::optional<double> curveShift;
    bool keepValidated = true; ///< keep Stage II's start, fit or their mix by validation points (StageTwoChoice.h)
    bool validatedSplit = true; ///< split what the validation points measure to pay (ValidatedSplit.h)
    bool keepPerGaussian = true; ///< then each Gaussian's version by validation points (GaussianChoice.h)
    /// With the keep: score Stage II's fit on the validation points every this many iterations and
    /// stop it once the score rose (StageTwoOptions::heldOutStop; 0: never).
    int validationStop = 10;
    /// Draws of the judge's rule behind the validation points (Judge.h: prepareValidationRest());
    /// 0: autoValidationDraws() of the rest model.
    int validationDraws = 0;
    HeldOutOptions heldOut; ///< points and seed of the judge (and of the training-lattice error)
    bool evaluate = true;   ///< the judge's errors of Stage I and Stage II in the report (and the training-lattice error)
    int evalEvery = 0;      ///< also record the held-out error every K Stage II iterations (0 = off)
    bool writeVdb = false;  ///< field.vdb: the Stage II model's field (same grids as `to-vdb`)
    bool render = false;    ///< compare.png: rest | Stage I | Stage II from a few orbit views; stretched.png: a close-up of the most stretched region
    int renderViews = 3;    ///< orbit views in compare.png
    int renderSize = 320;   ///< pixels per view (square)
    /// Where every computing step runs (auto: CUDA when compiled in and a GPU is present),
    /// resolved once by prepareDeformRest() (DeformRest::device); the device of the options above is not used.
    Device device = Device::Auto;
    /// The recipe the settings came from (report.json "recipe"; the settings themselves are above).
    nlohmann::json recipe;
};

/// @brief Whether --max-gaussians is met after the keep by merging split children back
///        (job/BudgetMerge.h): a budget, --budget-merge auto, the keep's validation points and a fit
///        that keeps its Gaussians (no Stage II split or prune); and, on a given model, a budget
///        above its count (at 1x nothing is split). Else the splits spend the budget.
bool mergesToBudget(const DeformJobOptions& o);

/// @brief The spec's graph block with the options' --nodes/--k/--seed overrides applied.
GraphOptions graphOptionsOf(const DeformSpec& spec, const DeformJobOptions& options);

/// @brief What a deform run computes from the rest model alone: the model, the deformation graph,
///        Stage I's rig (and device engine), the rest SampleGrid, the judge's rest side and the
///        training lattice's held-out rest side.
///        Shared by every frame of an animation; not copyable or movable (the engine refers to it).
struct DeformRest {
    ResolvedDevice device; ///< DeformJobOptions::device, resolved once for every frame
    GaussianCloud model;
    ReadReport read;
    std::vector<CloudWarning> warnings; ///< outliers that weaken a run (printed once, in each report)
    DeformationGraph graph;
    StageOneRig rig;
    std::unique_ptr<StageOneUpdater> stageOne;
    std::unique_ptr<SampleGrid> grid;           ///< null with stage1Only
    std::optional<JudgeRest> judge;              ///< the fixed judge's points and rest features (eval's)
    std::optional<JudgeRest> validation;         ///< the judge's rule with another seed: Stage II's choice
    std::optional<HeldOutPoints> latticePoints;  ///< training-lattice points X; warped per frame
    std::optional<FieldErrorTarget> latticeRest; ///< rest features at X with the grid's filter, not yet rotated
    double readMs = 0, graphMs = 0, rigMs = 0, sampleGridMs = 0, heldOutMs = 0, latticeMs = 0, validationMs = 0;

    DeformRest() = default;
    DeformRest(const DeformRest&) = delete;
    DeformRest& operator=(const DeformRest&) = delete;
};

/// @brief Read the model and compute the rest side for a graph (graphOptionsOf() of a spec).
std::unique_ptr<DeformRest> prepareDeformRest(const DeformJobOptions& options, const GraphOptions& graph);
/// @brief The rest side of a model already in memory (the Python module); options.input only names
///        it in messages and the report, and `read` is what the report says about its reading.
std::unique_ptr<DeformRest> prepareDeformRest(const DeformJobOptions& options, const GraphOptions& graph, GaussianCloud model,
                                              ReadReport read = {});

/// @brief Where one run of a spec writes; an empty path is not written (deformed: Stage II only).
struct FrameOutputs {
    std::string baseline, deformed, vdb, compare, report;
    std::string stretched; ///< close-up of the most stretched region (written with compare)
};

/// @brief Another start for Stage II than Stage I's model (animate's warm start), with a check
///        that can send the frame back to the cold start after seeing the fit.
struct StageTwoStart {
    /// Changes Stage II's starting model `start` (a copy of stage1.deformed) before the fit.
    std::function<void(const StageOneResult& stage1, GaussianCloud& start)> change;
    /// Sees the fit from the changed start; true: fit again from stage1.deformed and keep that fit.
    /// The report's "stage2" then says "start": "cold" and gives the rejected start's "warmEnergy".
    std::function<bool(const StageTwoReport& fit)> rejects;
};

/// @brief One frame computed and not yet written: its deformation, Stage I, Stage II's model
///        once refined, and the report so far.
struct FrameResult {
    Deformation deformation;
    StageOneResult stage1;
    std::optional<GaussianCloud> fitted; ///< none before refineFrame() (or with stage1Only)
    std::optional<StretchedRegion> stretched; ///< refineFrame() with render: the most stretched region (stretched.png)
    FrameReport report;                  ///< what each step did so far
    double ms = 0;                       ///< time spent on the frame so far
};

/// @brief Solve the spec from the rest pose and run Stage I; nothing is written.
FrameResult poseFrame(DeformRest& rest, const DeformSpec& spec, const DeformJobOptions& options);

/// @brief Stage II and the steps around it (warp, splits, fit, keep, judge) on a posed frame.
///        A RunControl installed on this thread (core/RunControl.h) sees each iteration and can
///        cancel (Cancelled is thrown; the frame is left without a fitted model).
/// @throws UsageError when the rest side was prepared for Stage I only.
void refineFrame(DeformRest& rest, const DeformJobOptions& options, FrameResult& frame, const StageTwoStart& start = {});

/// @brief Write a frame's outputs (the paths set in `out`; Stage II's only when refined) and
///        return its report (written to out.report when set).
FrameReport writeFrame(const DeformRest& rest, const DeformJobOptions& options, const FrameResult& frame,
                          const FrameOutputs& out);

/// @brief Solve the spec from the rest pose, run Stage I, warp a copy of the rest samples, run
///        Stage II, evaluate and write the outputs; returns the report (written to out.report
///        when set). The bytes of every output depend on the rest side and the spec only.
///        `written` (optional) receives the last model written (Stage II, or Stage I with stage1Only).
///        `start` (optional) changes Stage II's starting model, a copy of Stage I's (animate's warm
///        start; report "stage2" "start": "warm" or "cold"); the bytes then depend on it too. Not
///        called when Stage II is skipped (a rigid spec).
FrameReport runDeformFrame(DeformRest& rest, const DeformSpec& spec, const DeformJobOptions& options,
                           const FrameOutputs& out, GaussianCloud* written = nullptr, const StageTwoStart& start = {});

/// @brief Run the job and write its outputs (a DeformSession: pose, refine, write); returns the
///        report that was written to report.json.
/// @throws InputError / IoError with a message naming the file and the problem.
FrameReport runDeformJob(const DeformJobOptions& options);

} // namespace splatwarp
