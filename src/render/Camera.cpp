#include "render/Camera.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/Error.h"

namespace splatwarp {

namespace {

constexpr double kPi = 3.14159265358979323846;
double radians(double deg) { return deg * kPi / 180.0; }

Vec3d normalised(const Vec3d& v)
{
    const double n = length(v);
    return n > 0 ? v / n : v;
}

/// World-to-camera from camera-to-world rotation (OpenCV axes) and centre.
Camera fromCameraToWorld(const Mat3d& c2w, const Vec3d& centre)
{
    Camera cam;
    cam.rotation = c2w.transposed();
    cam.translation = -(cam.rotation * centre);
    return cam;
}

/// Quantile of one coordinate of the centres (nth_element on a copy).
double coordinateQuantile(const GaussianCloud& g, int axis, double q)
{
    std::vector<float> v(g.size());
    for (std::size_t i = 0; i < g.size(); ++i) v[i] = g.means[3 * i + std::size_t(axis)];
    const std::size_t k = std::min(v.size() - 1, std::size_t(std::floor(q * double(v.size() - 1) + 0.5)));
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
    return v[k];
}

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
    void checkIntrinsics(const Camera& c, const std::string& where) const
    {
        if (!(c.fx > 0 && c.fy > 0)) fail(where, "focal lengths must be positive");
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
        Camera cam = fromCameraToWorld(c2w, Vec3d(pos[0].get<double>(), pos[1].get<double>(), pos[2].get<double>()));
        cam.width = int(r.number(e, "width", where));
        cam.height = int(r.number(e, "height", where));
        cam.fx = r.number(e, "fx", where);
        cam.fy = r.number(e, "fy", where);
        // graphdeco cameras have a centred principal point.
        cam.cx = 0.5 * cam.width;
        cam.cy = 0.5 * cam.height;
        cam.name = e.contains("img_name") && e["img_name"].is_string() ? e["img_name"].get<std::string>()
                                                                      : msg("view_", i);
        r.checkIntrinsics(cam, where);
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
        Camera cam = fromCameraToWorld(c2w, Vec3d(m[3], m[7], m[11]));
        const double w = r.optionalNumber(f, top, "w", where), h = r.optionalNumber(f, top, "h", where);
        cam.width = std::isnan(w) ? o.width : int(w);
        cam.height = std::isnan(h) ? o.height : int(h);
        if (cam.width <= 0 || cam.height <= 0)
            r.fail(where, "no image size ('w', 'h') in the file; give one (render --size WxH)");
        const double flx = r.optionalNumber(f, top, "fl_x", where), fly = r.optionalNumber(f, top, "fl_y", where);
        const double angleX = r.optionalNumber(f, top, "camera_angle_x", where);
        const double angleY = r.optionalNumber(f, top, "camera_angle_y", where);
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
        cams.push_back(cam);
    }
    return cams;
}

} // namespace

Vec3d Camera::centre() const { return -(rotation.transposed() * translation); }

Camera Camera::resized(int newWidth, int newHeight) const
{
    Camera c = *this;
    const double sx = double(newWidth) / width, sy = double(newHeight) / height;
    c.fx *= sx;
    c.cx *= sx;
    c.fy *= sy;
    c.cy *= sy;
    c.width = newWidth;
    c.height = newHeight;
    return c;
}

PinholeView Camera::view() const
{
    PinholeView v;
    v.rotation = Mat3f::from(rotation);
    v.translation = Vec3f(translation);
    v.centre = Vec3f(centre());
    v.fx = float(fx);
    v.fy = float(fy);
    v.cx = float(cx);
    v.cy = float(cy);
    v.width = width;
    v.height = height;
    return v;
}

Camera Camera::lookAt(const Vec3d& eye, const Vec3d& target, const Vec3d& up, double fovYDeg, int width, int height)
{
    const Vec3d forward = normalised(target - eye);
    Vec3d right = cross(forward, up);
    if (length(right) < 1e-9 * length(up)) {
        // Looking along the up axis: any perpendicular "up" gives a valid (if arbitrary) roll.
        const Vec3d alt = std::abs(forward.x) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
        right = cross(forward, alt);
    }
    right = normalised(right);
    const Vec3d down = cross(forward, right);
    Camera c;
    for (int k = 0; k < 3; ++k) {
        c.rotation.m[0][k] = right[k];
        c.rotation.m[1][k] = down[k];
        c.rotation.m[2][k] = forward[k];
    }
    c.translation = -(c.rotation * eye);
    c.width = width;
    c.height = height;
    c.fy = 0.5 * height / std::tan(0.5 * radians(fovYDeg));
    c.fx = c.fy;
    c.cx = 0.5 * width;
    c.cy = 0.5 * height;
    return c;
}

Vec3d parseUpAxis(const std::string& name)
{
    const bool negative = !name.empty() && name[0] == '-';
    const std::string axis = name.substr(negative || (!name.empty() && name[0] == '+') ? 1 : 0);
    Vec3d v;
    if (axis == "x")
        v = Vec3d(1, 0, 0);
    else if (axis == "y")
        v = Vec3d(0, 1, 0);
    else if (axis == "z")
        v = Vec3d(0, 0, 1);
    else
        throw InputError(msg("unknown up axis '", name, "' (use x, y, z, -x, -y, -z or auto)"));
    return negative ? -v : v;
}

std::vector<Camera> orbitCameras(const GaussianCloud& cloud, const OrbitOptions& o)
{
    if (cloud.empty()) throw InputError("cannot place orbit cameras around an empty model");
    if (o.views < 1) throw InputError(msg("orbit needs at least one view, got ", o.views));
    if (!(o.fovDeg > 0 && o.fovDeg < 180)) throw InputError(msg("field of view must be in (0, 180) degrees, got ", o.fovDeg));
    if (!(o.distanceFactor > 0)) throw InputError(msg("distance factor must be positive, got ", o.distanceFactor));
    if (o.width <= 0 || o.height <= 0) throw InputError(msg("image size must be positive, got ", o.width, "x", o.height));
    Vec3d lo, hi;
    for (int a = 0; a < 3; ++a) {
        lo[a] = coordinateQuantile(cloud, a, o.boundsQuantile);
        hi[a] = coordinateQuantile(cloud, a, 1.0 - o.boundsQuantile);
    }
    const Vec3d centre = (lo + hi) * 0.5, extent = hi - lo;
    int upAxis = 0;
    Vec3d up;
    if (o.up == "auto") {
        for (int a = 1; a < 3; ++a)
            if (extent[a] < extent[upAxis]) upAxis = a;
        up[upAxis] = 1;
    } else {
        up = parseUpAxis(o.up);
        upAxis = up.x != 0 ? 0 : (up.y != 0 ? 1 : 2);
    }
    // The first camera looks across the longest horizontal axis (a bar is seen broadside).
    const int h0 = (upAxis + 1) % 3, h1 = (upAxis + 2) % 3;
    const int side = extent[h0] <= extent[h1] ? h0 : h1;
    Vec3d a;
    a[side] = 1;
    const Vec3d b = cross(up, a);
    double radius = 0.5 * length(extent);
    if (!(radius > 0)) radius = 1.0; // a single point: any scale will do
    const double halfFovY = 0.5 * radians(o.fovDeg);
    const double halfFovX = std::atan(std::tan(halfFovY) * double(o.width) / o.height);
    const double distance = o.distanceFactor * radius / std::sin(std::min(halfFovX, halfFovY));
    const double elevation = radians(o.elevationDeg);
    std::vector<Camera> cams;
    for (int k = 0; k < o.views; ++k) {
        const double azimuth = 2.0 * kPi * k / o.views;
        const Vec3d dir = (a * std::cos(azimuth) + b * std::sin(azimuth)) * std::cos(elevation) + up * std::sin(elevation);
        Camera c = Camera::lookAt(centre + dir * distance, centre, up, o.fovDeg, o.width, o.height);
        c.name = msg("view_", k);
        cams.push_back(c);
    }
    return cams;
}

std::vector<Camera> parseCameraFile(const std::string& jsonText, const std::string& path,
                                    const CameraFileOptions& options)
{
    Json top;
    try {
        top = Json::parse(jsonText);
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
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(msg(path, ": cannot open camera file"));
    std::stringstream text;
    text << in.rdbuf();
    return parseCameraFile(text.str(), path, options);
}

} // namespace splatwarp
