#include "render/Rasterizer.h"

#include "core/Error.h"
#include "render/TileRaster.h"

namespace splatwarp {

void checkRenderInputs(const GaussianCloud& cloud, const Camera& camera)
{
    cloud.checkConsistent();
    if (camera.width <= 0 || camera.height <= 0 || !(camera.fx > 0) || !(camera.fy > 0))
        throw InputError(msg("camera '", camera.name, "' needs a positive image size and focal length"));
}

Image renderGaussians(const GaussianCloud& cloud, const Camera& camera, const RenderOptions& options)
{
    checkRenderInputs(cloud, camera);
    const PinholeView view = pinholeView(camera);
    const detail::TileBins bins = detail::binSplats(cloud, view, options.threaded);
    Image image(view.width, view.height, 4);
    detail::compositeTiles(bins, options.background, options.threaded, image, nullptr);
    return image;
}

} // namespace splatwarp
