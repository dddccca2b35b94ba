#pragma once
/// @file TriangleMesh.h
/// @brief An unlit triangle mesh for image ground truth: positions, optional UVs and vertex
///        colours, one material per triangle (a colour and an optional texture).
/// @note  Colours are display values, as the splat colours (image/Image.h): a texel, a vertex
///        colour or a material colour is what the picture shows.
#include <cstdint>
#include <string>
#include <vector>

#include "core/SmallMath.h"
#include "image/Image.h"

namespace splatwarp {

/// @brief What a triangle shows: texture(uv) when it has a texture, else the vertex colours when
///        the mesh has them, else `colour`. A texture is also multiplied by the vertex colours.
struct MeshMaterial {
    Vec3f colour{1.0f, 1.0f, 1.0f}; ///< RGB when untextured and without vertex colours
    int texture = -1;               ///< index into TriangleMesh::textures, -1 for none
};

/// @brief Indexed triangles. V  #V vertices, F  #F triangles.
struct TriangleMesh {
    std::vector<float> positions;          ///< [V,3]
    std::vector<float> uvs;                ///< [V,2] or empty; v = 0 is the texture's bottom row
    std::vector<float> colours;            ///< [V,3] or empty
    std::vector<std::uint32_t> triangles;  ///< [F,3] vertex indices
    std::vector<std::uint32_t> materialOf; ///< [F] index into materials
    std::vector<MeshMaterial> materials;
    std::vector<Image> textures; ///< RGB or RGBA display values (alpha ignored)
    std::string name;            ///< the file it came from, for messages

    std::size_t vertexCount() const { return positions.size() / 3; }
    std::size_t triangleCount() const { return triangles.size() / 3; }
    Vec3f vertex(std::size_t i) const { return {positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]}; }
    /// @brief Throws InputError naming the mesh unless it has triangles, finite vertices, indices
    ///        and materials in range, and attribute arrays of the right sizes.
    void checkValid() const;
    /// @brief Axis-aligned bounds of the vertices (of the whole array, used or not).
    void bounds(Vec3d& lo, Vec3d& hi) const;
    /// @brief The colour triangle f shows at barycentric coordinates b (weights of its three
    ///        vertices): bilinear wrapped texel at the interpolated UV (v = 0 the bottom row), times
    ///        the interpolated vertex colour; or that colour; or the material's (see MeshMaterial).
    Vec3d colourAt(std::size_t f, const Vec3d& b) const;
};

/// @brief Replace the colours by a smooth procedural pattern of the position (three sinusoids of
///        about `periods` periods over the largest extent, one per channel, in [0.15, 0.85]) and
///        drop textures: a colour for meshes that have none (the Stanford bunny).
void applyProceduralColour(TriangleMesh& mesh, double periods = 3.0);

} // namespace splatwarp
