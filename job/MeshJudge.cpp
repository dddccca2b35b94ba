#include "job/MeshJudge.h"

#include <algorithm>
#include <numeric>
#include <utility>

#include "job/Judge.h"
#include "core/Error.h"
#include "deform/Deformation.h"
#include "deform/WarpPoints.h"
#include "image/BitmapFont.h"
#include "image/Metrics.h"
#include "render/RenderDevice.h"
#include "train/MeshViews.h"

namespace splatwarp {

namespace {

TriangleMesh warpedMesh(const TriangleMesh& mesh, const Deformation& d)
{
    TriangleMesh out = mesh;
    warpPoints(d.graph, d.transforms, mesh.positions.data(), mesh.vertexCount(), out.positions.data(), nullptr);
    return out;
}

constexpr int kMontagePad = 4;

/// Rows of (mesh | splats) for the given views, each labelled with its PSNR.
Image montage(const std::vector<Image>& truth, const std::vector<Image>& splats, const std::vector<std::size_t>& rows,
              const MeshJudgeReport& r)
{
    if (rows.empty()) return Image();
    const int w = truth[rows.front()].width, h = truth[rows.front()].height, pad = kMontagePad;
    Image sheet(2 * w + 3 * pad, int(rows.size()) * (h + pad) + pad, 3, 0.02f);
    for (std::size_t k = 0; k < rows.size(); ++k) {
        const int top = pad + int(k) * (h + pad);
        for (int side = 0; side < 2; ++side) {
            const Image& img = side == 0 ? truth[rows[k]] : splats[rows[k]];
            const int left = pad + side * (w + pad);
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x)
                    for (int c = 0; c < 3; ++c) sheet.at(left + x, top + y, c) = img.at(x, y, c);
        }
        drawText(sheet, pad + 2, top + 2, msg(r.names[rows[k]], " ", int(r.psnr[rows[k]] * 100) / 100.0, " dB"), 1,
                 Vec3f(1.0f, 1.0f, 0.3f));
    }
    return sheet;
}

} // namespace

TriangleMesh deformMesh(const TriangleMesh& mesh, const GaussianCloud& rest, const DeformSpec& spec)
{
    return warpedMesh(mesh, solveDeformation(rest, spec));
}

int montageRows(int worst, int w, int h)
{
    // 6 rows of 2800x2800 made a 5612x16828 sheet that compare then refused.
    if (worst <= 0 || 2 * w + 3 * kMontagePad > kMaxImageSide) return 0;
    return std::min(worst, (kMaxImageSide - kMontagePad) / (h + kMontagePad));
}

MeshJudgeReport judgeAgainstMesh(const TriangleMesh& restMesh, const GaussianCloud& rest, const GaussianCloud& deformed,
                                 const DeformSpec& spec, const MeshJudgeOptions& o)
{
    restMesh.checkValid();
    const Deformation d = solveDeformation(rest, spec);
    const TriangleMesh mesh = warpedMesh(restMesh, d);
    MeshJudgeReport r;
    std::vector<Camera> cameras;
    if (const std::optional<RigidMotion> motion = rigidMotionOf(d)) {
        r.rigid = true;
        for (const Camera& c : meshCameras(restMesh, o.views)) cameras.push_back(movedCamera(c, *motion));
    } else {
        cameras = meshCameras(mesh, o.views);
    }
    RenderOptions splatRender;
    splatRender.background = o.render.background;
    // Only the montage's views keep their pictures: all of them were held (200 views of 4096^2,
    // mesh and splats: 107 GB).
    const std::size_t keep = std::size_t(montageRows(o.worst, o.views.width, o.views.height));
    const auto worse = [&](std::size_t a, std::size_t b) { return std::make_pair(r.psnr[a], a) < std::make_pair(r.psnr[b], b); };
    std::vector<Image> truth(cameras.size()), splats(cameras.size());
    std::vector<std::size_t> order; // the worst views so far, worst first
    for (std::size_t v = 0; v < cameras.size(); ++v) {
        truth[v] = renderMesh(mesh, cameras[v], o.render);
        splats[v] = renderGaussians(deformed, cameras[v], splatRender);
        r.names.push_back(cameras[v].name);
        r.psnr.push_back(psnr(splats[v], truth[v]));
        r.ssim.push_back(ssim(splats[v], truth[v]));
        order.insert(std::upper_bound(order.begin(), order.end(), v, worse), v);
        if (order.size() > keep) {
            truth[order.back()] = Image();
            splats[order.back()] = Image();
            order.pop_back();
        }
    }
    r.meanPsnr = std::accumulate(r.psnr.begin(), r.psnr.end(), 0.0) / double(r.psnr.size());
    r.meanSsim = std::accumulate(r.ssim.begin(), r.ssim.end(), 0.0) / double(r.ssim.size());
    r.montage = montage(truth, splats, order, r);
    return r;
}

} // namespace splatwarp
