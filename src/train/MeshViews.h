#pragma once
/// @file MeshViews.h
/// @brief Meshes as training data: views rendered around a mesh (the ground truth of `from-mesh`
///        and of `eval --mesh`) and Gaussians sampled on its surface (a start for training).
#include <vector>

#include "mesh/MeshRasterizer.h"
#include "render/Camera.h"
#include "train/Trainer.h"

namespace splatwarp {

/// @brief The bounding sphere used to place views: the box centre and the largest vertex distance
///        from it (invariant under rigid motions of the vertices up to the box centre).
void meshSphere(const TriangleMesh& mesh, Vec3d& centre, double& radius);

/// @brief Sphere cameras (render/Camera.h) around the mesh's bounding sphere.
std::vector<Camera> meshCameras(const TriangleMesh& mesh, const SphereViewOptions& options);

/// @brief Render the mesh from every camera (RGB over options.background) as training views.
std::vector<TrainingView> renderMeshViews(const TriangleMesh& mesh, const std::vector<Camera>& cameras,
                                          const MeshRenderOptions& options);

/// @brief `count` Gaussians on the surface: triangles chosen by area, points uniform on them,
///        the surface colour there (TriangleMesh::colourAt()), opacity 0.1 (3DGS's init), flat
///        discs in the triangle's plane of the mean spacing sqrt(area / count).
/// @throws InputError for a mesh of zero area.
GaussianCloud meshSurfaceGaussians(const TriangleMesh& mesh, std::size_t count, unsigned seed);

} // namespace splatwarp
