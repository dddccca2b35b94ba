#pragma once
/// @file FrameReport.h
/// @brief What one deform frame computed, step by step, as typed records. The pipeline fills them
///        and reads them (animate's warm start, the manifest, the CLI's summary); report.json is
///        FrameReport::toJson(), made once at the edge (writeFrame()). Keys: docs/report-schema.md.
#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "deform/CurveSplit.h"
#include "io/CloudStats.h"
#include "job/BudgetMerge.h"
#include "job/GaussianChoice.h"
#include "job/Judge.h"
#include "job/StageTwoChoice.h"
#include "job/StageTwoRounds.h"
#include "job/ValidatedSplit.h"
#include "stage2/StageTwo.h"
#include "stage2/StageTwoOptions.h"
#include "vdb/SampleGrid.h"

namespace splatwarp {

/// @brief A judged model: the fixed judge's errors (what `eval` prints) and the error at the
///        training lattice (what Stage II fits), with that lattice's filter variance.
struct ModelErrors {
    JudgeReport judge;
    FieldErrorReport lattice;
    double latticeFilterVariance = 0;
};

/// @brief The curve split (deform/CurveSplit.h) and, with validation points, fans against none.
struct CurveSplitRecord {
    CurveSplitOptions options;
    bool fans = true;                        ///< false: the split without fans was judged better
    std::optional<double> validationWithFans, validationWithoutFans;
    int roundsUsed = 0;
    std::size_t split = 0, added = 0, gaussians = 0;
    std::size_t pruned = 0;                  ///< faint Gaussians removed to make room for children
    double ms = 0;
    std::optional<ModelErrors> errors;       ///< judged when it added Gaussians
};

/// @brief The validated split (job/ValidatedSplit.h) within the budget the curve split left.
struct ValidatedSplitRecord {
    ValidatedSplitReport result;
    std::size_t budget = 0;
};

/// @brief The curve shift the validation points chose, with each share's score.
struct CurveShiftRecord {
    double share = 0;
    bool automatic = false; ///< the share was chosen among kCurveShares
    std::vector<double> shares, scores;
    double ms = 0;
    std::optional<ModelErrors> errors;
};

/// @brief The validated keep: the candidates' names, the choice among them and, when the
///        Gaussians are the same in every candidate, the per-Gaussian choice after it.
struct KeepRecord {
    std::vector<std::string> candidates;
    StageTwoChoice choice;
    std::optional<GaussianChoiceReport> perGaussian;
    double ms() const { return choice.ms + (perGaussian ? perGaussian->ms : 0.0); }
};

/// @brief One held-out evaluation during Stage II (--eval-every).
struct CurvePoint {
    int iteration = 0;
    FieldErrorReport error;
};

/// @brief Stage II: the fit, its grid and settings, the Gaussians gained and lost, the keep.
struct StageTwoRecord {
    bool skipped = false;                 ///< a rigid spec: Stage I's model is the result
    StageTwoReport fit;
    SampleGridStats grid;
    SampleGridOptions gridOptions;
    StageTwoOptions options;
    DensifyJobOptions densify;
    double densifyMs = 0;
    std::size_t gaussiansAdded = 0, gaussiansRemoved = 0, gaussians = 0;
    std::optional<std::size_t> gaussianBudget; ///< `--max-gaussians`: the most the output may hold
    std::optional<BudgetMergeReport> budgetMerge; ///< the budget met after the keep (job/BudgetMerge.h)
    std::optional<std::string> start;     ///< animate --warm-start: "warm" or "cold"
    std::optional<double> warmEnergy;     ///< the rejected warm start's energy
    std::optional<double> warmLimit;      ///< animate: the energy a warm start had to stay under
    std::optional<std::vector<CurvePoint>> evalCurve;
    std::optional<KeepRecord> keep;
    std::optional<ModelErrors> errors;
};

/// @brief Where stretched.png looks.
struct StretchedRecord {
    std::size_t cell = 0;
    double stretch = 0, radius = 0;
    Vec3d centre;
};

/// @brief One frame's report. Times are in ms by step name ("read", "stage2", ...).
struct FrameReport {
    // The input and the settings it ran with.
    std::string inputPath, inputFormat, specPath;
    std::size_t inputGaussians = 0;
    int inputShDegree = 0;
    std::vector<CloudWarning> inputWarnings; ///< outliers of the input that weaken the run (io/CloudStats.h outlierWarnings())
    nlohmann::json recipe; ///< the recipe's own description (job/Recipe.h), null without one
    nlohmann::json settings; ///< every setting's value (job/DeformSettings.h settingsJson(); animate hashes the same)
    /// The ED solve's and Stage I's records (graph, handles, solver, stage1, their timings), as
    /// deform/DeformReport.h makes them; written out, never read.
    nlohmann::json stageOne;
    std::string stage1Shape;
    // The steps' results, in run order; a step that did not run has none.
    std::optional<ModelErrors> stage1Errors;
    std::optional<std::string> warpDevice;
    std::optional<CurveSplitRecord> curveSplit;
    std::optional<ValidatedSplitRecord> validatedSplit;
    std::optional<CurveShiftRecord> curveShift;
    std::optional<StageTwoRecord> stage2;
    std::optional<StretchedRecord> stretched;
    std::map<std::string, std::string> outputs; ///< by kind ("baseline", "deformed", ...)
    std::map<std::string, double> timingsMs;

    /// @brief report.json of the frame.
    nlohmann::json toJson() const;
};

/// @brief JSON of a judged model's two errors, as the report's stages hold them.
void modelErrorsJson(const ModelErrors& errors, nlohmann::json& stage);

} // namespace splatwarp
