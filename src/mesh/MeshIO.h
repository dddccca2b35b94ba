#pragma once
/// @file MeshIO.h
/// @brief Reading meshes (OBJ, PLY, glTF/GLB, OFF and the other formats assimp knows) with their
///        materials, UV textures (PNG or JPEG, files or embedded) and vertex colours.
#include <string>

#include "mesh/TriangleMesh.h"

namespace splatwarp {

/// @brief Options for readMesh().
struct MeshReadOptions {
    /// Texture for materials without one (the Spot OBJ ships its PNG without a .mtl); "" for none.
    std::string texture;
    /// Colour the mesh with applyProceduralColour() (for meshes without colours, the bunny).
    bool proceduralColour = false;
};

/// @brief Read a mesh file; node transforms are baked into the vertices, polygons triangulated,
///        points and lines dropped. Texture paths are relative to the mesh's folder.
/// @throws InputError naming the file for an unreadable, empty or invalid mesh (no triangles,
///         non-finite vertices) and for a texture that is missing or not a PNG/JPEG.
TriangleMesh readMesh(const std::string& path, const MeshReadOptions& options = {});

} // namespace splatwarp
