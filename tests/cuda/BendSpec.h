#pragma once
/// @file BendSpec.h
/// @brief samples/specs/bend.json for the GPU parity tests: from the source tree they were built
///        in, or relative to the working directory (a test bundle run from a repository copy on a
///        GPU machine, where the build's absolute path does not exist).
#include <filesystem>
#include <string>

#include "deform/DeformSpec.h"

namespace splatwarp::test {

inline DeformSpec loadBendSpec()
{
    const std::string built = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json";
    return loadDeformSpec(std::filesystem::exists(built) ? built : std::string("samples/specs/bend.json"));
}

} // namespace splatwarp::test
