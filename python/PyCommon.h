#pragma once
/// @file PyCommon.h
/// @brief What the Python module's files share: paths, errors, keyword settings as CLI flags.
#include <mutex>
#include <string>

#include <CLI/CLI.hpp>
#include <pybind11/pybind11.h>

#include "core/GaussianCloud.h"

namespace splatwarp::python {

/// @brief A str or os.PathLike as a path string, in the file system's encoding (os.fsencode: names
///        that are not UTF-8 work); TypeError otherwise, ValueError for an embedded NUL (the file
///        opened would be another than the one named).
std::string pathOf(const pybind11::handle& path);

/// @brief One library call at a time across Python threads: the library's OutputSet (the files a
///        call writes, and the files it read that none of them may replace: core/AtomicFile.h) is
///        one per process, and two calls at once shared it. Waits for its turn without the GIL.
///        Every module function that reads or writes files, or runs a job, takes one first.
class LibraryTurn {
public:
    LibraryTurn();

private:
    std::unique_lock<std::mutex> mLock;
};

/// @brief What every CLI command reads for a model (tools/ReadArgs.h readModel()): the readers,
///        the unusable-Gaussian rule and "holds no Gaussians".
GaussianCloud readModelFile(const std::string& path, bool dropInvalid);

/// @brief A model in memory checked as a file is when read: its arrays are writable numpy views,
///        so NaN, unusable values or no Gaussians at all may have come in after it was made.
/// @throws InputError naming `name` as the readers do.
void checkModelInMemory(const std::string& name, GaussianCloud& cloud);

/// @brief A copy of a Model argument checked with checkModelInMemory(), or a path read with
///        readModelFile(); `name` receives the path, or `inMemory` for a model in memory.
GaussianCloud modelOrPath(const pybind11::handle& value, std::string& name, const std::string& inMemory = "(model)");

/// @brief Parse keyword settings as the flags of `sub` (iterations=50 -> --iterations 50, a True
///        flag given, False or None left out) with the CLI's own definitions and checks.
/// @throws TypeError naming an unknown keyword; ValueError with the flag's message for a bad value.
void parseSettings(CLI::App& app, CLI::App* sub, const std::string& function, const pybind11::kwargs& settings);

/// @brief splatwarp.Error (a ValueError): every library error, with the message the CLI prints.
void bindErrors(pybind11::module_& m);

/// @brief deform, to_vdb, from_vdb, render, eval.
void bindJobs(pybind11::module_& m);

} // namespace splatwarp::python
