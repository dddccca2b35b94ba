#pragma once
/// @file DeformReport.h
/// @brief The Stage I part of report.json, shared by `deform --stage1-only` and the full pipeline.
#include <nlohmann/json.hpp>

#include "deform/Deformation.h"
#include "deform/StageOne.h"

namespace splatwarp {

/// @brief JSON of a solved deformation and its Stage I result: graph, handles (nodes per handle,
///        reassignments, residuals), solver (iterations, energies before/after, weights), moving
///        counts and timings in ms ("graph", "resolve", "solve", "weights", "update").
nlohmann::json stageOneReportJson(const Deformation& deformation, const StageOneResult& stageOne,
                                  const GraphOptions& graphOptions, const EdOptions& edOptions);

} // namespace splatwarp
