#include "io/CameraFileWriter.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "core/AtomicFile.h"
#include "core/Error.h"

namespace splatwarp {

void writeGraphdecoCameras(const std::string& path, const std::vector<Camera>& cameras)
{
    nlohmann::json list = nlohmann::json::array();
    for (std::size_t i = 0; i < cameras.size(); ++i) {
        const Camera& c = cameras[i];
        if (std::abs(c.cx - 0.5 * c.width) > 1e-6 * c.width || std::abs(c.cy - 0.5 * c.height) > 1e-6 * c.height)
            throw InputError(msg(path, ": camera '", c.name, "' has its principal point off the image centre"));
        const Mat3d c2w = c.rotation.transposed();
        const Vec3d p = c.centre();
        nlohmann::json rows = nlohmann::json::array();
        for (int r = 0; r < 3; ++r) rows.push_back({c2w.m[r][0], c2w.m[r][1], c2w.m[r][2]});
        list.push_back({{"id", i}, {"img_name", c.name}, {"width", c.width}, {"height", c.height},
                        {"position", {p.x, p.y, p.z}}, {"rotation", rows}, {"fx", c.fx}, {"fy", c.fy}});
    }
    writeFileAtomic(path, list.dump(1) + "\n");
}

} // namespace splatwarp
