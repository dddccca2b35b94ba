#pragma once
/// @file Judge.h
/// @brief The fixed judge of `eval` and of the `deform` / `animate` reports (README "eval"): the
///        held-out field error at drawJudgePoints() (the rest model alone decides the points; no
///        low-pass filter on either side), pushed through the spec's own deformation, and for a
///        rigid spec the image PSNR against the rest model seen from the inversely moved cameras.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "job/HeldOutEval.h"
#include "image/Image.h"
#include "render/Camera.h"
#include "render/Rasterizer.h"

namespace splatwarp {

class PointBlocks;

/// @brief x = rotation X + translation.
struct RigidMotion {
    Mat3d rotation = Mat3d::identity();
    Vec3d translation;
};

/// @brief The one rigid motion of a rigid spec: every graph node held by a handle (fixed or
///        moved) and one rigid motion taking every node to its target (within 1e-9 of the nodes'
///        extent); nothing otherwise. The solved node transforms follow it to the ED solver's tolerance.
std::optional<RigidMotion> rigidMotionOf(const Deformation& deformation);

/// @brief A rest camera moved with the model: it sees the moved model as the rest one saw the rest.
Camera movedCamera(const Camera& restCamera, const RigidMotion& motion);

/// @brief Image PSNR over all views and colour channels (display RGB on black, peak 1).
struct ImagePsnr {
    double db = 0.0;   ///< +infinity for identical images
    int views = 0;
    int size = 0;      ///< pixels per view (square)
};

/// @brief What the judge says about one model.
struct JudgeReport {
    FieldErrorReport field;
    std::optional<ImagePsnr> psnr; ///< rigid specs only
};

/// @brief fieldErrorJson() keys, plus "imagePsnr" {db (null when infinite), views, size} for a rigid spec.
nlohmann::json judgeJson(const JudgeReport& report);

/// @brief The lines `eval` prints for a report (and `deform` for each stage), '\n'-terminated.
std::string judgeText(const JudgeReport& report);

/// @brief The rest side of the judge (once per rest model): its points and rest features, unrotated.
struct JudgeRest {
    HeldOutPoints points;
    FieldErrorTarget unrotated;
};

/// @brief drawJudgePoints() and the rest features there, on options.device.
JudgeRest prepareJudgeRest(const GaussianCloud& rest, const HeldOutOptions& options);

/// Draws of the judge's rule behind the validation points of a large model (auto's fewest); each
/// keeps 1/kValidationDraws of the counts below, so twice the draws keep twice the points.
constexpr int kValidationDraws = 10;
/// `--validation-draws auto`: kValidationWork / the rest model's Gaussians, from kValidationDraws to
/// twice that. The keep and the budget merge choose each Gaussian on the points it reaches, and twice
/// the points choose better on every row measured (judged error -0.5% to -4.2%; the image judge level)
/// for about twice the keep's time, which grows with the model: small models (up to 31k Gaussians)
/// get 20 draws, guitar (91k) 10 (docs/lab/gaussian-budget.md, "Twice the validation points").
constexpr std::size_t kValidationWork = 620000;
int autoValidationDraws(std::size_t gaussians);
/// Points the validation keeps at kValidationDraws, in the judge's points: this many inside the rest
/// model (O_rest > 0)...
constexpr double kValidationInside = 1.6;
/// ...and this many outside it.
constexpr double kValidationOutside = 0.4;

/// @brief The validation side (Stage II's choices): `draws` point sets of the judge's rule (seeds
///        options.seed, +1, ...), thinned to about kValidationInside x options.points inside the
///        rest model and kValidationOutside x outside it (times draws / kValidationDraws), each
///        point weighted by one over its keep probability, so the sums estimate the judge's (times
///        draws / kValidationDraws; the scores, relative errors, do not scale). On captured scenes
///        most of the judge's region is empty (train-1000: 6% of the points inside), and the
///        choices among candidates need many more points where the Gaussians are than the judge's
///        count gives. The points at rest only (warped and rotations empty: the Judge makes them).
JudgeRest prepareValidationRest(const GaussianCloud& rest, const HeldOutOptions& options, int draws = kValidationDraws);

/// @brief The judge of one deformation: the points warped and the rest side rotated once; for a
///        rigid spec, the ground-truth images rendered once. Everything runs on the device of
///        the rest side's points (points.features.device).
class Judge {
public:
    /// Views and size of the rigid-spec PSNR renders (orbit cameras around the rest model).
    static constexpr int kViews = 4, kSize = 256;

    Judge(const GaussianCloud& restModel, const JudgeRest& rest, const Deformation& deformation, bool threaded = true);
    /// @brief The field error and, for a rigid spec, the image PSNR of a deformed model.
    JudgeReport judge(const GaussianCloud& deformed) const;
    /// @brief The field error alone (the Stage II curve).
    FieldErrorReport fieldError(const GaussianCloud& deformed) const;
    /// @brief Per point: opacity error over the target's sum plus colour error over its sum (the
    ///        terms of fieldError()'s opacity + color).
    std::vector<double> pointScores(const GaussianCloud& deformed) const;
    /// @brief The sum of pointScores(): opacity + colour relative L1 (a validation score).
    double score(const GaussianCloud& deformed) const;
    /// @brief A deformed model's features [P, shStride] and opacity [P] at the warped points.
    struct Evaluation {
        std::vector<float> features, opacity;
    };
    /// @brief The block engine's evaluation of a deformed model at the points (what every method
    ///        above compares with the target).
    std::shared_ptr<const Evaluation> evaluate(const GaussianCloud& deformed) const;
    /// @brief Keep the latest evaluations (by a 128-bit hash of each model's contents) within
    ///        `bytes` (the latest always): the deform pipeline's choices evaluate the same model
    ///        again (the keep scores the curve shift's pick and the last check's fit, and its
    ///        per-Gaussian step the kept mix). 0: keep none (the default).
    void rememberEvaluations(std::size_t bytes);
    /// @brief Drop the most recently used remembered evaluation (one the caller knows it will not
    ///        ask for again); nothing without remembering.
    void forgetLatest();
    /// The points: X and x = phi(X) (the rotations went into target() and are not kept).
    const HeldOutPoints& points() const { return mPoints; }
    /// The rest side at the points, SH rotated (what pointScores() compares with).
    const FieldErrorTarget& target() const { return mTarget; }
    bool rigid() const { return !mTruth.empty(); }

private:
    struct Memo;
    FieldPointErrors pointErrors(const GaussianCloud& deformed) const;
    void checkSizes() const;
    /// pointScores()' weights: one over the target's sums (0 where a sum is 0).
    double opacityScale() const { return mTarget.sumOpacity > 0 ? 1.0 / mTarget.sumOpacity : 0.0; }
    double colorScale() const { return mTarget.sumFeatures > 0 ? 1.0 / mTarget.sumFeatures : 0.0; }
    HeldOutPoints mPoints;
    FieldErrorTarget mTarget;
    std::shared_ptr<Memo> mMemo; ///< shared by copies (the same points and target)
    std::shared_ptr<const PointBlocks> mBlocks; ///< the warped points in blocks (CPU), cut once
    RenderOptions mRender; ///< the device of the renders
    std::vector<Camera> mMovedCameras; ///< the rest cameras moved with the model
    std::vector<Image> mTruth;         ///< the rest model from the rest cameras
};

/// @brief Refuse `points` held-out points (and, with draws > 0, the validation points of that many
///        draws) past `maxMemoryBytes` (0: no limit) before any is drawn; `flag` names the count
///        in the message (--eval-points, --points).
/// @throws InputError
void checkEvalPointMemory(std::size_t points, int featureFloats, bool judge, int draws, std::size_t maxMemoryBytes,
                          const char* flag);

} // namespace splatwarp
