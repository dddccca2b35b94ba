#pragma once
/// @file DeformSession.h
/// @brief The deform pipeline as a session, for the editor and for library users: the rest side
///        is prepared once; pose(spec) gives Stage I (and the ED solve) without touching disk;
///        refine() runs the rest with progress per iteration and a cancel; write(dir) writes what
///        `deform` writes. `deform` itself is pose, refine, write (runDeformJob()).
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "job/DeformPipeline.h"
#include "core/RunControl.h"

namespace splatwarp {

/// @brief Before any work: refuse a deform into options.outDir whose outputs could not be written
///        (a symlink, a folder or a device where a file goes; an input, also one a --stage1-only run
///        would remove as an earlier run's result). Creates nothing. @throws IoError.
void checkDeformOutputs(const DeformJobOptions& options);

class DeformSession {
public:
    /// @brief Read the model and prepare the rest side for the graph of `graphSpec` (its graph
    ///        block with the options' --nodes/--k/--seed; every later spec must share it).
    ///        With options.stage1Only, no sample grid is made and refine() is refused.
    /// @throws InputError / IoError naming the file, as deform does.
    DeformSession(DeformJobOptions options, const DeformSpec& graphSpec);
    /// @brief The same for a model already in memory (options.input only names it).
    DeformSession(DeformJobOptions options, const DeformSpec& graphSpec, GaussianCloud model);
    ~DeformSession();
    DeformSession(const DeformSession&) = delete;
    DeformSession& operator=(const DeformSession&) = delete;

    const DeformRest& rest() const { return *mRest; }
    const DeformJobOptions& options() const { return mOptions; }
    /// @brief Refuse a spec whose graph block (with the options' --nodes/--k/--seed) is not the
    ///        session's. @throws InputError naming the spec.
    void checkGraph(const DeformSpec& spec) const;

    /// @brief The ED solve from the rest pose and Stage I for a spec; forgets an earlier refine.
    /// @throws InputError when the spec's graph block differs from the session's.
    const StageOneResult& pose(const DeformSpec& spec);

    /// @brief What preview() gives: the posed model at SH degree 0 and the times of its two parts.
    struct Preview {
        const GaussianCloud& cloud;
        std::size_t moving = 0;
        double solveMs = 0, updateMs = 0;
    };
    /// @brief A live pose for a drag: the ED solve warm-started from the last solve of this session
    ///        and Stage I's means, rotations and scales only, in float (applyStageOnePreview();
    ///        withShDegree(rest, 0): no SH rotation, DC as rest). Within the solver's tolerance of
    ///        pose(spec) and float's rounding, not bit-equal: refine() and
    ///        write() pose the previewed spec exactly first, so what they give is pose()'s. A session
    ///        whose Stage I runs on CUDA poses exactly (the device update is not the cost there).
    /// @throws InputError as pose().
    Preview preview(const DeformSpec& spec);

    /// @brief Stage II and the recipe's other steps on the last pose. `control` sees each Stage II
    ///        iteration; setting its cancel flag stops within one iteration (Cancelled is thrown,
    ///        the pose is kept, nothing is written).
    /// @throws UsageError without a pose or with options.stage1Only.
    const GaussianCloud& refine(const RunControl& control = {});

    /// @brief Write what `deform -o dir` writes for the last pose (and refine): baseline.ply,
    ///        deformed.ply, report.json and the extras the options ask for, all together or none;
    ///        a stale deformed.ply of an earlier refine is removed. Returns the report
    ///        (report.json is its toJson()). `extraFiles` (name, contents) are written into dir with
    ///        them (the editor's spec.json).
    FrameReport write(const std::string& dir, const std::vector<std::pair<std::string, std::string>>& extraFiles = {});

    bool refined() const { return mFrame && mFrame->fitted.has_value(); }
    /// @brief The last pose's report so far: what write() returns less the outputs and the write timings.
    /// @throws UsageError without a pose.
    const FrameReport& report() const;

private:
    DeformJobOptions mOptions;
    GraphOptions mGraph;
    std::unique_ptr<DeformRest> mRest;
    std::optional<FrameResult> mFrame;
    double mRestMs = 0;
    std::optional<DeformSpec> mPreviewed;      ///< the last preview()'s spec, not yet posed exactly
    std::optional<NodeTransforms> mLastSolve;  ///< the warm start of the next preview()
    std::optional<GaussianCloud> mPreviewCloud;

    void poseThePreview(); ///< pose() the previewed spec, if one waits
};

} // namespace splatwarp
