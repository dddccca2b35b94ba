#include "io/CameraFiles.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/JsonText.h"

namespace splatwarp {

namespace {

using Json = nlohmann::json;

/// Parse errors name the file and the element; every accessor below goes through these.
struct JsonReader {
    const std::string& path;

    [[noreturn]] void fail(const std::string& where, const std::string& what) const
    {
        throw InputError(msg(path, ": ", where.empty() ? "" : where + ": ", what));
    }
    const Json& field(const Json& obj, const char* key, const std::string& where) const
    {
        if (!obj.is_object()) fail(where, "expected a JSON object");
        const auto it = obj.find(key);
        if (it == obj.end()) fail(where, msg("missing '", key, "'"));
        return *it;
    }
    double number(const Json& obj, const char* key, const std::string& where) const
    {
        const Json& v = field(obj, key, where);
        if (!v.is_number()) fail(where, msg("'", key, "' must be a number"));
        const double d = v.get<double>();
        if (!std::isfinite(d)) fail(where, msg("'", key, "' must be finite"));
        return d;
    }
    /// Number from the first object that has the key (per-frame, then top level); NaN if none.
    double optionalNumber(const Json& first, const Json& second, const char* key, const std::string& where) const
    {
        if (first.is_object() && first.contains(key)) return number(first, key, where);
        if (second.is_object() && second.contains(key)) return number(second, key, where);
        return std::nan("");
    }
    /// rows x cols numbers as a list of rows.
    std::vector<double> matrix(const Json& obj, const char* key, int rows, int cols, const std::string& where) const
    {
        const Json& m = field(obj, key, where);
        std::vector<double> out;
        if (!m.is_array() || int(m.size()) != rows) fail(where, msg("'", key, "' must be a ", rows, "x", cols, " matrix"));
        for (const Json& row : m) {
            if (!row.is_array() || int(row.size()) != cols)
                fail(where, msg("'", key, "' must be a ", rows, "x", cols, " matrix"));
            for (const Json& v : row) {
                if (!v.is_number() || !std::isfinite(v.get<double>()))
                    fail(where, msg("'", key, "' has a non-numeric entry"));
                out.push_back(v.get<double>());
            }
        }
        return out;
    }
    /// An image side: a whole number of pixels in [1, kMaxImageSide] (an int cast of 8e9 is undefined).
    int imageSide(double v, const char* key, const std::string& where) const
    {
        if (!(v >= 1 && v <= kMaxImageSide && v == std::floor(v)))
            fail(where, msg("'", key, "' must be a whole number of pixels from 1 to ", kMaxImageSide, ", got ", v));
        return int(v);
    }
    /// A camera's rotation: orthonormal columns (to 1e-2: files round) and no mirror. A zero, scaled
    /// or reflected matrix rendered, and trained on, without a word before.
    void checkRotation(const Mat3d& r, const char* key, const std::string& where) const
    {
        const Mat3d gram = r.transposed() * r; // the columns' dot products: the identity for a rotation
        double worst = 0;
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) worst = std::max(worst, std::fabs(gram.m[a][b] - (a == b ? 1.0 : 0.0)));
        const double det = r.determinant();
        if (!(worst <= 1e-2)) fail(where, msg("'", key, "' is not a rotation (its columns are not orthonormal: off by ", worst, ")"));
        if (det < 0) fail(where, msg("'", key, "' is a mirror (determinant ", det, "), not a rotation"));
    }
    void checkIntrinsics(const Camera& c, const std::string& where) const
    {
        // A zero camera angle gives an infinite focal length: a blank image, not an error, before.
        if (!(c.fx > 0 && c.fy > 0 && std::isfinite(c.fx) && std::isfinite(c.fy)))
            fail(where, "focal lengths must be positive and finite (a camera angle in (0, pi) radians)");
        if (!std::isfinite(c.cx) || !std::isfinite(c.cy)) fail(where, "principal point must be finite");
        if (c.width <= 0 || c.height <= 0) fail(where, "image size must be positive");
    }
};

std::vector<Camera> readGraphdeco(const JsonReader& r, const Json& list)
{
    std::vector<Camera> cams;
    for (std::size_t i = 0; i < list.size(); ++i) {
        const Json& e = list[i];
        const std::string where = msg("camera ", i);
        const std::vector<double> rot = r.matrix(e, "rotation", 3, 3, where);
        const Json& pos = r.field(e, "position", where);
        if (!pos.is_array() || pos.size() != 3 || !pos[0].is_number() || !pos[1].is_number() || !pos[2].is_number())
            r.fail(where, "'position' must be 3 numbers");
        Mat3d c2w;
        for (int k = 0; k < 9; ++k) c2w.m[k / 3][k % 3] = rot[std::size_t(k)];
        Camera cam = Camera::fromCameraToWorld(c2w, Vec3d(pos[0].get<double>(), pos[1].get<double>(), pos[2].get<double>()));
        cam.width = r.imageSide(r.number(e, "width", where), "width", where);
        cam.height = r.imageSide(r.number(e, "height", where), "height", where);
        cam.fx = r.number(e, "fx", where);
        cam.fy = r.number(e, "fy", where);
        // graphdeco cameras have a centred principal point.
        cam.cx = 0.5 * cam.width;
        cam.cy = 0.5 * cam.height;
        cam.name = e.contains("img_name") && e["img_name"].is_string() ? e["img_name"].get<std::string>()
                                                                      : msg("view_", i);
        r.checkIntrinsics(cam, where);
        r.checkRotation(c2w, "rotation", where);
        cams.push_back(cam);
    }
    return cams;
}

std::vector<Camera> readTransforms(const JsonReader& r, const Json& top, const CameraFileOptions& o)
{
    const Json& frames = r.field(top, "frames", "");
    if (!frames.is_array()) r.fail("", "'frames' must be a list");
    std::vector<Camera> cams;
    for (std::size_t i = 0; i < frames.size(); ++i) {
        const Json& f = frames[i];
        const std::string where = msg("frame ", i);
        const std::vector<double> m = r.matrix(f, "transform_matrix", 4, 4, where);
        // OpenGL camera axes (x right, y up, z backward) -> OpenCV (x right, y down, z forward):
        // negate the second and third columns of the rotation.
        Mat3d c2w;
        for (int row = 0; row < 3; ++row)
            for (int col = 0; col < 3; ++col) c2w.m[row][col] = m[std::size_t(4 * row + col)] * (col == 0 ? 1.0 : -1.0);
        Camera cam = Camera::fromCameraToWorld(c2w, Vec3d(m[3], m[7], m[11]));
        const double w = r.optionalNumber(f, top, "w", where), h = r.optionalNumber(f, top, "h", where);
        cam.width = std::isnan(w) ? o.width : r.imageSide(w, "w", where);
        cam.height = std::isnan(h) ? o.height : r.imageSide(h, "h", where);
        if (cam.width <= 0 || cam.height <= 0)
            r.fail(where, "no image size ('w', 'h') in the file; give one (render --size WxH)");
        const double flx = r.optionalNumber(f, top, "fl_x", where), fly = r.optionalNumber(f, top, "fl_y", where);
        const double angleX = r.optionalNumber(f, top, "camera_angle_x", where);
        const double angleY = r.optionalNumber(f, top, "camera_angle_y", where);
        // tan() of 7 rad (beyond pi) is positive too: such an angle made a camera of 0.72 rad
        for (const auto& [angle, key] : {std::pair{angleX, "camera_angle_x"}, std::pair{angleY, "camera_angle_y"}})
            if (!std::isnan(angle) && !(angle > 0 && angle < M_PI))
                r.fail(where, msg("'", key, "' must be in (0, pi) radians, got ", angle));
        if (!std::isnan(flx))
            cam.fx = flx;
        else if (!std::isnan(angleX))
            cam.fx = 0.5 * cam.width / std::tan(0.5 * angleX);
        else
            r.fail(where, "needs 'fl_x' or 'camera_angle_x'");
        if (!std::isnan(fly))
            cam.fy = fly;
        else if (!std::isnan(angleY))
            cam.fy = 0.5 * cam.height / std::tan(0.5 * angleY);
        else
            cam.fy = cam.fx; // square pixels
        const double cx = r.optionalNumber(f, top, "cx", where), cy = r.optionalNumber(f, top, "cy", where);
        cam.cx = std::isnan(cx) ? 0.5 * cam.width : cx;
        cam.cy = std::isnan(cy) ? 0.5 * cam.height : cy;
        cam.name = f.contains("file_path") && f["file_path"].is_string() ? f["file_path"].get<std::string>()
                                                                        : msg("view_", i);
        r.checkIntrinsics(cam, where);
        r.checkRotation(c2w, "transform_matrix", where);
        cams.push_back(cam);
    }
    return cams;
}

} // namespace

std::vector<Camera> parseCameraFile(const std::string& jsonText, const std::string& path,
                                    const CameraFileOptions& options)
{
    Json top;
    try {
        top = parseJson(jsonText);
    } catch (const Json::exception& e) { // parse_error, and out_of_range for numbers beyond double (fuzz)
        throw InputError(msg(path, ": not valid JSON: ", e.what()));
    }
    const JsonReader reader{path};
    std::vector<Camera> cams;
    if (top.is_array())
        cams = readGraphdeco(reader, top);
    else if (top.is_object() && top.contains("frames"))
        cams = readTransforms(reader, top, options);
    else
        reader.fail("", "neither a graphdeco cameras.json (a list) nor a transforms.json (an object with 'frames')");
    if (cams.empty()) reader.fail("", "contains no cameras");
    return cams;
}

std::vector<Camera> readCameraFile(const std::string& path, const CameraFileOptions& options)
{
    return parseCameraFile(readWholeFile(path, "camera file"), path, options);
}

} // namespace splatwarp
