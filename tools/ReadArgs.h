#pragma once
/// @file ReadArgs.h
/// @brief `--drop-invalid` and model reading shared by every command that reads a model.
#include <string>

#include "Command.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "io/GaussianIO.h"
#include "job/DeformSettings.h"

namespace splatwarp::cli {

/// @brief What every command that reads a model reads (docs/formats.md has the table).
inline const std::string kModelFormats =
    "(.ply graphdeco or compressed, .splat, .spz, .sog or its meta.json folder, .glb, .vdb points; detected by content)";

inline void addDropInvalidFlag(CLI::App* sub, bool& dropInvalid)
{
    sub->add_flag("--drop-invalid", dropInvalid, deformSetting("--drop-invalid").help);
}

/// @brief readGaussians() with the flag applied; notes (e.g. how many were dropped) go to progress.
inline GaussianCloud readModel(const std::string& path, bool dropInvalid, ReadReport* report = nullptr)
{
    ReadOptions options;
    options.dropInvalid = dropInvalid;
    ReadReport local;
    GaussianCloud cloud = readGaussians(path, options, &local);
    for (const std::string& note : local.notes) progress(path + ": " + note);
    if (cloud.empty())
        throw InputError(local.dropped ? msg(path, ": no Gaussians left after dropping ", local.dropped, " unusable ones")
                                       : msg(path, ": the file holds no Gaussians"));
    if (report) *report = std::move(local);
    return cloud;
}

} // namespace splatwarp::cli
