#pragma once
/// @file VdbLibrary.h
/// @brief OpenVDB library lifetime and version, kept behind a plain header so callers need no
///        OpenVDB includes.
#include <string>

namespace splatwarp::vdb {

/// @brief Call openvdb::initialize() once (grid types registered); safe to call repeatedly.
void initialize();
/// @brief "OpenVDB 10.0.1 (ABI 10), NanoVDB 32.4.2".
std::string libraryVersions();

} // namespace splatwarp::vdb
