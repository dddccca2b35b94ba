#pragma once
/// @file DeformSpec.h
/// @brief The deformation spec (JSON): graph options and handles that pin or move graph nodes.
///        Format documented in samples/specs/README.md; the shape is a contract (extend, don't change).
#include <string>
#include <vector>

#include "core/SmallMath.h"
#include "deform/DeformationGraph.h"

namespace splatwarp {

/// @brief One handle: a node selection (box, sphere or explicit node list) and what happens to it.
struct HandleSpec {
    enum class Select { Box, Sphere, Nodes };
    Select select = Select::Box;
    Vec3d boxMin, boxMax;            ///< Select::Box (spec units)
    Vec3d centre;                    ///< Select::Sphere (spec units)
    double radius = 0;               ///< Select::Sphere (spec units)
    std::vector<int> nodes;          ///< Select::Nodes: graph node indices
    bool fixed = false;              ///< pin the nodes at rest (hard constraint); no motion keys allowed
    double scale = 1.0;              ///< uniform scale about the pivot
    Vec3d axis{0, 0, 1};             ///< rotation axis (normalised on load)
    double degrees = 0;              ///< rotation angle about axis through the pivot
    bool hasPivot = false;           ///< else the centroid of the selected nodes
    Vec3d pivot;                     ///< spec units
    Vec3d translate;                 ///< spec units (bbox: fractions of the extent per axis)
};

/// @brief A parsed deformation spec.
struct DeformSpec {
    enum class Units { World, Bbox };
    std::string source = "<spec>";   ///< file name (or label) used in error messages
    int version = 1;
    Units units = Units::World;      ///< bbox: positions in the normalised centre bounding box (0..1 per axis)
    GraphOptions graph;              ///< the "graph" block (defaults from GraphOptions)
    std::vector<HandleSpec> handles;
};

/// @brief Parse a spec from JSON text. sourceName names it in errors.
/// @throws InputError naming sourceName and the handle index: unknown keys, wrong types, non-finite
///         numbers, zero rotation axis, wrong version, a handle without exactly one selection.
DeformSpec parseDeformSpec(const std::string& jsonText, const std::string& sourceName);

/// @brief Read and parse a spec file. @throws IoError if unreadable, InputError as parseDeformSpec.
DeformSpec loadDeformSpec(const std::string& path);

} // namespace splatwarp
