#pragma once
/// @file MeshRasterizer.h
/// @brief CPU rasteriser for unlit triangle meshes: near-plane clipping, z-buffer, perspective-
///        correct UVs and vertex colours, bilinear textures. The camera model and pixel centres are
///        those of the splat rasteriser (render/SplatProjection.h), so the two images align.
#include "core/Camera.h"
#include "image/Image.h"
#include "mesh/TriangleMesh.h"

namespace splatwarp {

/// @brief Options for renderMesh().
struct MeshRenderOptions {
    Vec3f background{0.0f, 0.0f, 0.0f}; ///< RGB where no triangle is seen (display values)
    /// Samples per pixel along each axis, box-filtered: 1 = one sample at the pixel centre; 2-4
    /// give anti-aliased edges, closer to what splats can reproduce.
    int samples = 1;
    bool threaded = true; ///< oneTBB over bands of rows (the result does not depend on it)
};

/// Camera-space depth (world units) where triangles are clipped: small, since orbit cameras stay
/// far from the mesh, but positive so no vertex projects through z = 0.
constexpr double kMeshNearPlane = 1e-3;

/// @brief Render a mesh (checkValid() first).
/// @return RGBA display values; A = covered fraction of the pixel's samples, RGB composited
///         over the background (covered colour x A + background x (1 - A)).
/// @throws InputError for an invalid mesh or a camera without a positive size and focal length.
Image renderMesh(const TriangleMesh& mesh, const Camera& camera, const MeshRenderOptions& options = {});

} // namespace splatwarp
