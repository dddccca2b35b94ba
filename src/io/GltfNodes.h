#pragma once
/// @file GltfNodes.h
/// @brief The glTF node graph (internal to the .glb reader): which node instantiates which mesh with
///        what global transform, and applying such a transform to splats.
#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/GaussianCloud.h"
#include "core/SmallMath.h"

namespace splatwarp {

/// @brief x -> m x + t.
struct NodeTransform {
    Mat3d m = Mat3d::identity();
    Vec3d t{0, 0, 0};
};

/// @brief A mesh placed by a node.
struct MeshInstance {
    std::size_t mesh;
    NodeTransform transform;
};

/// @brief Every node of the default scene (or, without scenes, of every root) holding a mesh, in
///        depth-first order, with its global transform. Empty when the file has no nodes.
/// @throws InputError for a malformed transform, a missing node or a node reached twice.
std::vector<MeshInstance> meshInstances(const std::string& path, const nlohmann::json& doc);

/// @brief Move splats by a node transform: centres by m x + t; quaternions, SH by its rotation;
///        log scales by the log of its scale.
/// @throws InputError unless m is a rotation times a uniform positive scale (mirrors, shears and
///         non-uniform scales are refused: a Gaussian would need a new orientation per axis).
void applyNodeTransform(const std::string& path, const NodeTransform& t, GaussianCloud& g);

} // namespace splatwarp
