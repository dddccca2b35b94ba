#pragma once
/// @file TrainJob.h
/// @brief `train` and `from-mesh` end to end: data in, splats trained, model, views and a report
///        written through one OutputSet (all or nothing).
#include <nlohmann/json.hpp>
#include <string>

#include "mesh/MeshIO.h"
#include "train/MeshViews.h"
#include "train/TrainingData.h"

namespace splatwarp {

class OutputSet;

/// @brief What a training run produced.
struct TrainOutcome {
    GaussianCloud model;
    TrainReport report;
    ViewScores test; ///< held-out views (empty when there are none)
};

/// @brief Train `init` on data.train and score data.test; progress lines on the way.
TrainOutcome trainAndScore(const GaussianCloud& init, const Dataset& data, const TrainOptions& options);

/// @brief report.json of a run: counts, seconds, options, held-out PSNR/SSIM (mean and per view).
nlohmann::json trainReportJson(const TrainOutcome& outcome, const Dataset& data, const TrainOptions& options);

/// @brief Options of fromMesh().
struct FromMeshOptions {
    MeshReadOptions read;
    SphereViewOptions views;       ///< training views (views.views of them)
    int testViews = 20;            ///< held-out views: another lattice (phase 0.5)
    MeshRenderOptions render{Vec3f(0.0f, 0.0f, 0.0f), 2}; ///< 2x2 samples (anti-aliased edges); background from train
    std::size_t initGaussians = 20000; ///< surface samples to start from
    TrainOptions train;
    /// `--max-memory`: views that would not fit are refused before any is rendered; 0: no limit.
    std::size_t maxMemoryBytes = 0;
};

/// @brief Read the mesh, render its views, train from surface samples.
/// @param data receives the rendered views (train and test)
TrainOutcome fromMesh(const std::string& meshPath, const FromMeshOptions& options, Dataset& data);

/// @brief Write views as DIR/cameras.json + DIR/images/NAME.png (readDataset() reads it back).
void writeViews(const std::string& dir, const std::vector<TrainingView>& views);

/// @brief Before any work, for writeViews() into `dir` (and `dir`/test when `withTest`): its
///        images/ and test/ are folders of dir itself (a symlink planted there would take the
///        pictures elsewhere), none of `others` (the command's other outputs) lies where the
///        pictures go, and the cameras.json files are claimed as outputs of `outputs`.
/// @throws IoError.
void checkViewsDir(OutputSet& outputs, const std::string& dir, bool withTest, const std::vector<std::string>& others);

} // namespace splatwarp
