#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "job/Judge.h"
#include "job/MeshJudge.h"
#include "deform/Deformation.h"
#include "core/AtomicFile.h"
#include "io/GaussianIO.h"
#include "train/MeshViews.h"
#include "support/TestSupport.h"

namespace splatwarp {
namespace {

/// A box with vertex colours, as an OBJ (v x y z r g b), quads triangulated by the reader.
const char* kBoxObj = "v -0.6 -0.3 -0.4 0.9 0.2 0.1\nv 0.6 -0.3 -0.4 0.2 0.9 0.1\nv -0.6 0.3 -0.4 0.1 0.2 0.9\n"
                      "v 0.6 0.3 -0.4 0.9 0.9 0.2\nv -0.6 -0.3 0.4 0.2 0.9 0.9\nv 0.6 -0.3 0.4 0.9 0.2 0.9\n"
                      "v -0.6 0.3 0.4 0.5 0.5 0.5\nv 0.6 0.3 0.4 0.1 0.1 0.1\n"
                      "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n";

TriangleMesh boxMesh()
{
    TriangleMesh m;
    m.name = "box";
    const float v[8][6] = {{-0.6f, -0.3f, -0.4f, 0.9f, 0.2f, 0.1f}, {0.6f, -0.3f, -0.4f, 0.2f, 0.9f, 0.1f},
                           {-0.6f, 0.3f, -0.4f, 0.1f, 0.2f, 0.9f},  {0.6f, 0.3f, -0.4f, 0.9f, 0.9f, 0.2f},
                           {-0.6f, -0.3f, 0.4f, 0.2f, 0.9f, 0.9f},  {0.6f, -0.3f, 0.4f, 0.9f, 0.2f, 0.9f},
                           {-0.6f, 0.3f, 0.4f, 0.5f, 0.5f, 0.5f},   {0.6f, 0.3f, 0.4f, 0.1f, 0.1f, 0.1f}};
    for (const auto& p : v) {
        m.positions.insert(m.positions.end(), {p[0], p[1], p[2]});
        m.colours.insert(m.colours.end(), {p[3], p[4], p[5]});
    }
    m.triangles = {0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3};
    m.materialOf.assign(12, 0);
    m.materials = {MeshMaterial()};
    return m;
}

/// The box's own splats: dense opaque surface samples (not a trained model; any PSNR will do).
GaussianCloud boxSplats(const TriangleMesh& m)
{
    GaussianCloud g = meshSurfaceGaussians(m, 6000, 1);
    for (float& o : g.opacities) o = 3.0f;
    return g;
}

/// The splats moved by a rigid motion (SH degree 0: nothing to rotate in the colours).
GaussianCloud movedSplats(const GaussianCloud& g, const RigidMotion& m)
{
    GaussianCloud out = g;
    for (std::size_t i = 0; i < g.size(); ++i) {
        out.setMean(i, Vec3f(m.rotation * Vec3d(g.mean(i)) + m.translation));
        const Quatf q = g.rotation(i);
        const Quat<double> r = matrixToQuat(m.rotation * quatToMatrix(Quat<double>{q.w, q.x, q.y, q.z}));
        out.setRotation(i, Quatf{float(r.w), float(r.x), float(r.y), float(r.z)});
    }
    return out;
}

const char* kAllFixed = R"({"version": 1, "units": "bbox", "graph": {"nodes": 32, "k": 8, "seed": 0},
  "handles": [{"box": {"min": [-0.01, -0.01, -0.01], "max": [1.01, 1.01, 1.01]}, "fixed": true}]})";
const char* kRigid = R"({"version": 1, "units": "bbox", "graph": {"nodes": 32, "k": 8, "seed": 0},
  "handles": [{"box": {"min": [-0.01, -0.01, -0.01], "max": [1.01, 1.01, 1.01]},
   "rotate": {"axis": [1, 1, 0], "degrees": 45}, "pivot": [0.5, 0.5, 0.5], "translate": [0.25, 0.0, 0.0]}]})";

// A rigid spec moves mesh and splats alike and the cameras with them: the rest PSNR again.
TEST(MeshJudgeTest, RigidSpecGivesTheRestPsnr)
{
    const TriangleMesh mesh = boxMesh();
    const GaussianCloud splats = boxSplats(mesh);
    MeshJudgeOptions o;
    o.views.views = 12;
    o.views.width = o.views.height = 64;
    const MeshJudgeReport rest = judgeAgainstMesh(mesh, splats, splats, parseDeformSpec(kAllFixed, "fixed"), o);
    EXPECT_TRUE(rest.rigid);
    EXPECT_GT(rest.meanPsnr, 15.0);
    EXPECT_EQ(rest.psnr.size(), 12u);
    EXPECT_EQ(rest.montage.height, 6 * (64 + 4) + 4); // the six worst views
    // Only the montage's views keep their pictures while the rest are judged: its rows are the
    // first six of the montage that keeps all twelve, worst first.
    MeshJudgeOptions all = o;
    all.worst = 12;
    const MeshJudgeReport every = judgeAgainstMesh(mesh, splats, splats, parseDeformSpec(kAllFixed, "fixed"), all);
    ASSERT_EQ(every.montage.height, 12 * (64 + 4) + 4);
    ASSERT_EQ(every.montage.width, rest.montage.width);
    const std::size_t rowFloats = std::size_t(rest.montage.width) * 3;
    const std::size_t sixRows = std::size_t(6 * (64 + 4) + 4) * rowFloats;
    EXPECT_TRUE(std::equal(rest.montage.pixels.begin(), rest.montage.pixels.begin() + std::ptrdiff_t(sixRows - 4 * rowFloats),
                           every.montage.pixels.begin()));

    // The splats moved by exactly the rigid motion the spec asks for.
    const DeformSpec rigid = parseDeformSpec(kRigid, "rigid");
    const TriangleMesh movedMesh = deformMesh(mesh, splats, rigid);
    GaussianCloud moved = splats;
    const Vec3d a0(mesh.vertex(0)), a1(mesh.vertex(7)), m0(movedMesh.vertex(0)), m1(movedMesh.vertex(7));
    EXPECT_NEAR(length(m1 - m0), length(a1 - a0), 1e-4); // the mesh moved rigidly
    const MeshJudgeReport still = judgeAgainstMesh(mesh, splats, moved, rigid, o);
    EXPECT_TRUE(still.rigid);
    EXPECT_LT(still.meanPsnr, rest.meanPsnr - 3.0); // unmoved splats: far off
    // Moving the splats along with the motion (what Stage I does for a rigid spec).
    const std::optional<RigidMotion> motion = rigidMotionOf(solveDeformation(splats, rigid));
    ASSERT_TRUE(motion.has_value());
    const MeshJudgeReport ok = judgeAgainstMesh(mesh, splats, movedSplats(splats, *motion), rigid, o);
    EXPECT_NEAR(ok.meanPsnr, rest.meanPsnr, 0.05);
    EXPECT_NEAR(ok.meanSsim, rest.meanSsim, 1e-3);
}

TEST(MeshJudgeTest, EvalMeshCommandPrintsPerViewScoresAndWritesTheMontage)
{
    test::TempDir dir;
    writeFileAtomic(dir.file("box.obj"), kBoxObj);
    writePly(dir.file("box.ply"), boxSplats(boxMesh()));
    writeFileAtomic(dir.file("fixed.json"), kAllFixed);
    const std::string out = dir.file("out.json");
    ASSERT_EQ(test::runCli("-q eval --mesh " + dir.file("box.obj") + " --rest " + dir.file("box.ply") + " --deformed " +
                               dir.file("box.ply") + " --spec " + dir.file("fixed.json") + " --views 5 --size 48 --json --montage " +
                               dir.file("worst.png"),
                           out),
              0)
        << test::fileBytes(out);
    const nlohmann::json j = nlohmann::json::parse(test::fileBytes(out));
    EXPECT_EQ(j["views"].size(), 5u);
    EXPECT_GT(j["psnr"].get<double>(), 15.0);
    EXPECT_TRUE(std::filesystem::exists(dir.file("worst.png")));
    EXPECT_EQ(test::runCli("eval --mesh " + dir.file("nothere.obj") + " --rest " + dir.file("box.ply") + " --deformed " +
                               dir.file("box.ply") + " --spec " + dir.file("fixed.json"),
                           out),
              1);
    EXPECT_NE(test::fileBytes(out).find("nothere.obj"), std::string::npos);
}

} // namespace
} // namespace splatwarp
