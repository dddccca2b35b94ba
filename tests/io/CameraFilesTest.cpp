#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/CameraFiles.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

using test::project;

/// Message of the InputError thrown by reading `path`, or "" when none.
std::string readError(const std::string& path, const CameraFileOptions& o = {})
{
    try {
        readCameraFile(path, o);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

TEST(CameraFilesTest, GraphdecoCamerasJson)
{
    test::TempDir dir;
    const std::string path = dir.file("cameras.json");
    // Camera at (0, 0, -5) looking along +z: camera-to-world rotation = identity. The second one is
    // rotated 90 degrees about y (its forward axis, column 2 of the rotation, is -x).
    writeFileAtomic(path, R"([
      {"id": 0, "img_name": "a", "width": 64, "height": 48, "position": [0, 0, -5],
       "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "fx": 50, "fy": 60},
      {"id": 1, "img_name": "b", "width": 32, "height": 32, "position": [5, 0, 0],
       "rotation": [[0, 0, -1], [0, 1, 0], [1, 0, 0]], "fx": 40, "fy": 40}])");
    const auto cams = readCameraFile(path);
    ASSERT_EQ(cams.size(), 2u);
    EXPECT_EQ(cams[0].name, "a");
    EXPECT_EQ(cams[0].width, 64);
    EXPECT_EQ(cams[0].height, 48);
    EXPECT_DOUBLE_EQ(cams[0].fy, 60);
    EXPECT_NEAR(cams[0].centre().z, -5, 1e-12);
    const Vec3d o0 = project(cams[0], Vec3d(0, 0, 0));
    EXPECT_NEAR(o0.x, 32, 1e-9);
    EXPECT_NEAR(o0.y, 24, 1e-9);
    EXPECT_NEAR(o0.z, 5, 1e-9);
    // +y world is image-down for an OpenCV camera with identity pose.
    EXPECT_GT(project(cams[0], Vec3d(0, 1, 0)).y, 24);
    const Vec3d o1 = project(cams[1], Vec3d(0, 0, 0));
    EXPECT_NEAR(o1.x, 16, 1e-9);
    EXPECT_NEAR(o1.z, 5, 1e-9);
    // Its right axis (column 0) is +z.
    EXPECT_GT(project(cams[1], Vec3d(0, 0, 1)).x, 16);
}

TEST(CameraFilesTest, NerfTransformsJson)
{
    test::TempDir dir;
    const std::string path = dir.file("transforms.json");
    // OpenGL camera at (0, 0, 4) with identity rotation looks along -z, y up.
    writeFileAtomic(path, R"({"camera_angle_x": 0.8, "w": 100, "h": 80,
      "frames": [{"file_path": "./r_0", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]},
                 {"file_path": "./r_1", "fl_x": 70, "cx": 40,
                  "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]})");
    const auto cams = readCameraFile(path);
    ASSERT_EQ(cams.size(), 2u);
    EXPECT_EQ(cams[0].name, "./r_0");
    EXPECT_NEAR(cams[0].fx, 50.0 / std::tan(0.4), 1e-9);
    EXPECT_NEAR(cams[0].fy, cams[0].fx, 1e-12);
    const Vec3d o = project(cams[0], Vec3d(0, 0, 0));
    EXPECT_NEAR(o.x, 50, 1e-9);
    EXPECT_NEAR(o.y, 40, 1e-9);
    EXPECT_NEAR(o.z, 4, 1e-9);
    EXPECT_LT(project(cams[0], Vec3d(0, 1, 0)).y, 40); // world up is image up
    EXPECT_GT(project(cams[0], Vec3d(1, 0, 0)).x, 50);
    EXPECT_DOUBLE_EQ(cams[1].fx, 70); // per-frame intrinsics override
    EXPECT_DOUBLE_EQ(cams[1].cx, 40);

    // Blender-style file without a size: needs the fallback.
    const std::string noSize = dir.file("nosize.json");
    writeFileAtomic(noSize, R"({"camera_angle_x": 0.8, "frames": [{"transform_matrix":
      [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]})");
    EXPECT_NE(readError(noSize).find("no image size"), std::string::npos);
    CameraFileOptions o2;
    o2.width = o2.height = 20;
    EXPECT_EQ(readCameraFile(noSize, o2)[0].width, 20);
}

TEST(CameraFilesTest, MalformedFilesNameTheProblem)
{
    test::TempDir dir;
    const auto expectError = [&](const std::string& name, const std::string& text, const std::string& part) {
        const std::string path = dir.file(name);
        writeFileAtomic(path, text);
        const std::string e = readError(path);
        EXPECT_NE(e.find(path), std::string::npos) << e;
        EXPECT_NE(e.find(part), std::string::npos) << e;
    };
    expectError("bad.json", "[{\"id\": 0,", "not valid JSON");
    expectError("nofx.json", R"([{"width": 4, "height": 4, "position": [0,0,0], "rotation": [[1,0,0],[0,1,0],[0,0,1]]}])",
                "camera 0: missing 'fx'");
    expectError("rot.json", R"([{"width": 4, "height": 4, "position": [0,0,0], "rotation": [[1,0,0],[0,1,0]], "fx": 1, "fy": 1}])",
                "'rotation' must be a 3x3 matrix");
    expectError("mat.json", R"({"camera_angle_x": 1, "w": 4, "h": 4, "frames": [{"transform_matrix": [[1,0,0,0]]}]})",
                "frame 0: 'transform_matrix' must be a 4x4 matrix");
    expectError("nofocal.json", R"({"w": 4, "h": 4, "frames": [{"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})",
                "needs 'fl_x' or 'camera_angle_x'");
    expectError("other.json", R"({"cameras": []})", "neither");
    // tan() of 7 rad is positive too: it rendered a camera of 0.72 rad with exit 0.
    expectError("angle.json", R"({"camera_angle_x": 7, "w": 4, "h": 4, "frames": [{"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})",
                "frame 0: 'camera_angle_x' must be in (0, pi) radians, got 7");
    expectError("empty.json", "[]", "no cameras");
    // Found by fuzz_cameras: a number beyond double made nlohmann throw out_of_range, not parse_error.
    expectError("overflow.json", R"({"camera_angle_x": 4.8, "w": 10e2222, "frames": []})", "not valid JSON");
    // Found by fuzz_cameras: 'w' of 8.4e9 was cast to int (undefined behaviour) before any check.
    expectError("hugew.json", R"({"camera_angle_x": 1, "w": 8.44444e9, "h": 4, "frames": [{"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,1,0,0],[0,0,0,1]]}]})",
                "frame 0: 'w' must be a whole number of pixels from 1 to 16384");
    expectError("halfh.json", R"([{"width": 4, "height": 2.5, "position": [0,0,0], "rotation": [[1,0,0],[0,1,0],[0,0,1]], "fx": 1, "fy": 1}])",
                "camera 0: 'height' must be a whole number of pixels");
    expectError("zerow.json", R"([{"width": 0, "height": 4, "position": [0,0,0], "rotation": [[1,0,0],[0,1,0],[0,0,1]], "fx": 1, "fy": 1}])",
                "camera 0: 'width' must be a whole number of pixels");
    // A rotation that is none: zero, scaled, mirrored (they rendered and trained before).
    expectError("zerorot.json", R"([{"width": 4, "height": 4, "position": [0,0,0], "rotation": [[0,0,0],[0,0,0],[0,0,0]], "fx": 1, "fy": 1}])",
                "camera 0: 'rotation' is not a rotation");
    expectError("scaled.json", R"({"camera_angle_x": 1, "w": 4, "h": 4, "frames": [{"transform_matrix": [[2,0,0,0],[0,2,0,0],[0,0,2,0],[0,0,0,1]]}]})",
                "frame 0: 'transform_matrix' is not a rotation");
    expectError("mirror.json", R"([{"width": 4, "height": 4, "position": [0,0,0], "rotation": [[-1,0,0],[0,1,0],[0,0,1]], "fx": 1, "fy": 1}])",
                "camera 0: 'rotation' is a mirror");
    EXPECT_THROW(readCameraFile(dir.file("missing.json")), IoError);
}

} // namespace
} // namespace splatwarp
