#pragma once
/// @file MeshJudge.h
/// @brief The paper's judge (`eval --mesh`): the mesh deformed by the same deformation as the
///        splats (the spec's graph built on the rest splats, its skinning applied to the vertices),
///        both rendered from the same views spread over the sphere, compared by PSNR and SSIM.
/// @note  LPIPS, the paper's third metric, needs pretrained network weights (VGG/AlexNet) that this
///        machine cannot fetch; it is not approximated.
#include <vector>

#include "deform/DeformSpec.h"
#include "mesh/MeshRasterizer.h"
#include "render/Camera.h"

namespace splatwarp {

/// @brief Options of judgeAgainstMesh().
struct MeshJudgeOptions {
    SphereViewOptions views{200};  ///< 200 views as the paper's Table 1, 256x256 by default
    MeshRenderOptions render{Vec3f(0.0f, 0.0f, 0.0f), 2}; ///< 2x2 samples: as from-mesh's training views
    int worst = 6;                 ///< rows of the montage: the views with the lowest PSNR
};

/// @brief The montage rows (of views of w x h pixels) that fit in a picture our readers read
///        (kMaxImageSide a side), at most `worst`; 0 when two views side by side are too wide.
int montageRows(int worst, int w, int h);

/// @brief Per-view and mean image scores; the montage (mesh | splats per row, worst first).
struct MeshJudgeReport {
    std::vector<std::string> names;
    std::vector<double> psnr, ssim;
    double meanPsnr = 0, meanSsim = 0;
    bool rigid = false; ///< the cameras moved with the spec's rigid motion
    Image montage;
};

/// @brief Deform the mesh's vertices with the spec (graph on `rest`), render it and `deformed`
///        from the same cameras: around the deformed mesh's bounding sphere, or for a rigid spec
///        the rest mesh's cameras moved with the motion (so a rigid edit scores the rest PSNR).
/// @throws InputError as solveDeformation(), readMesh() and the renderers.
MeshJudgeReport judgeAgainstMesh(const TriangleMesh& restMesh, const GaussianCloud& rest, const GaussianCloud& deformed,
                                 const DeformSpec& spec, const MeshJudgeOptions& options = {});

/// @brief The mesh's vertices pushed through a spec's deformation built on `rest`.
TriangleMesh deformMesh(const TriangleMesh& mesh, const GaussianCloud& rest, const DeformSpec& spec);

} // namespace splatwarp
