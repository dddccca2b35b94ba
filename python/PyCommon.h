#pragma once
/// @file PyCommon.h
/// @brief What the Python module's files share: paths, errors, keyword settings as CLI flags.
#include <string>

#include <CLI/CLI.hpp>
#include <pybind11/pybind11.h>

#include "core/GaussianCloud.h"

namespace splatwarp::python {

/// @brief A str or os.PathLike as a path string (TypeError otherwise).
std::string pathOf(const pybind11::handle& path);

/// @brief What every CLI command reads for a model (tools/ReadArgs.h readModel()): the readers,
///        the unusable-Gaussian rule and "holds no Gaussians".
GaussianCloud readModelFile(const std::string& path, bool dropInvalid);

/// @brief A Model argument as it is, or a path read with readModelFile(); `name` receives the
///        path, or "(model)" for a model in memory.
GaussianCloud modelOrPath(const pybind11::handle& value, std::string& name);

/// @brief Parse keyword settings as the flags of `sub` (iterations=50 -> --iterations 50, a True
///        flag given, False or None left out) with the CLI's own definitions and checks.
/// @throws TypeError naming an unknown keyword; ValueError with the flag's message for a bad value.
void parseSettings(CLI::App& app, CLI::App* sub, const std::string& function, const pybind11::kwargs& settings);

/// @brief splatwarp.Error (a ValueError): every library error, with the message the CLI prints.
void bindErrors(pybind11::module_& m);

/// @brief deform, to_vdb, from_vdb, render, eval.
void bindJobs(pybind11::module_& m);

} // namespace splatwarp::python
