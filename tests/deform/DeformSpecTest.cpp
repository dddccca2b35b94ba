#include <gtest/gtest.h>

#include "core/Error.h"
#include "deform/Deformation.h"
#include "deform/DeformSpec.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

namespace {

/// Message of the InputError thrown by f, or "" if none.
template <typename F>
std::string inputError(F f)
{
    try {
        f();
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

std::string parseError(const std::string& text)
{
    return inputError([&] { parseDeformSpec(text, "my.json"); });
}

const char* kGood = R"({"version":1,"units":"bbox","graph":{"nodes":32,"k":6,"seed":3},
 "handles":[{"box":{"min":[0,0,0],"max":[0.2,1,1]},"fixed":true},
            {"sphere":{"center":[1,0.5,0.5],"radius":0.2},"scale":1.5,"rotate":{"axis":[0,0,2],"degrees":90},
             "pivot":[1,0.5,0.5],"translate":[0,0.1,0]},
            {"nodes":[3,1],"translate":[0,0.1,0]}]})";

} // namespace

// |axis| overflowed for [1e200, 0, 0]: the axis became the zero vector and the rotation a collapse
// (the same judged numbers as "scale": 1e-300).
TEST(DeformSpec, RotationAxesOfAnyMagnitudeAreUnitAxes)
{
    for (const char* axis : {"[1e200, 0, 0]", "[1e-200, 0, 0]", "[3, 0, 0]"}) {
        const DeformSpec s = parseDeformSpec(std::string(R"({"version":1,"handles":[{"nodes":[0],"rotate":{"axis":)") + axis +
                                                 R"(,"degrees":90}}]})",
                                             "axis.json");
        EXPECT_NEAR(s.handles[0].axis.x, 1.0, 1e-15) << axis;
        EXPECT_EQ(s.handles[0].axis.y, 0.0) << axis;
    }
    EXPECT_NE(parseError(R"({"version":1,"handles":[{"nodes":[0],"rotate":{"axis":[0,0,0],"degrees":9}}]})").find("zero vector"),
              std::string::npos);
}

TEST(DeformSpec, ParsesTheDocumentedShape)
{
    const DeformSpec s = parseDeformSpec(kGood, "my.json");
    EXPECT_EQ(s.units, DeformSpec::Units::Bbox);
    EXPECT_EQ(s.graph.nodes, 32);
    EXPECT_EQ(s.graph.k, 6);
    EXPECT_EQ(s.graph.seed, 3u);
    ASSERT_EQ(s.handles.size(), 3u);
    EXPECT_TRUE(s.handles[0].fixed);
    EXPECT_EQ(s.handles[1].select, HandleSpec::Select::Sphere);
    EXPECT_DOUBLE_EQ(s.handles[1].axis.z, 1.0); // normalised
    EXPECT_DOUBLE_EQ(s.handles[1].scale, 1.5);
    EXPECT_EQ(s.handles[2].nodes, (std::vector<int>{3, 1}));
    for (const char* f : {"bend.json", "twist.json", "rigid.json"})
        EXPECT_NO_THROW(loadDeformSpec(std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/" + f)) << f;
}

TEST(DeformSpec, ErrorsNameTheFileAndHandle)
{
    std::string e = parseError(R"({"version":1,"handles":[{"nodes":[0]},{"nodes":[1],"rotation":{}}]})");
    EXPECT_NE(e.find("my.json"), std::string::npos) << e;
    EXPECT_NE(e.find("handle 1"), std::string::npos) << e;
    EXPECT_NE(e.find("rotation"), std::string::npos) << e;

    e = parseError(R"({"version":1,"handles":[{"nodes":[0],"translate":[0,1e999,0]}]})");
    EXPECT_NE(e.find("handle 0"), std::string::npos) << e;
    e = parseError(R"({"version":1,"handles":[{"nodes":[0]},{"nodes":[1],"translate":[0,NaN,0]}]})");
    EXPECT_NE(e.find("my.json: handle 1"), std::string::npos) << e;
    EXPECT_NE(e.find("NaN"), std::string::npos) << e;
    e = parseError(R"({"version":1,"handles":[{"sphere":{"center":[0,0,0],"radius":-1}}]})");
    EXPECT_NE(e.find("my.json: handle 0: sphere.radius"), std::string::npos) << e;

    e = parseError(R"({"version":1,"handles":[{"nodes":[0],"rotate":{"axis":[0,0,0],"degrees":5}}]})");
    EXPECT_NE(e.find("handle 0"), std::string::npos) << e;
    EXPECT_NE(e.find("zero"), std::string::npos) << e;

    e = parseError(R"({"version":1,"handles":[{"box":{"min":[0,0,0]}}]})");
    EXPECT_NE(e.find("my.json: handle 0: \"box\" needs \"max\""), std::string::npos) << e;
    e = parseError(R"({"version":2,"handles":[{"nodes":[0]}]})");
    EXPECT_NE(e.find("version"), std::string::npos) << e;
    e = parseError(R"({"version":1,"handles":[{"nodes":[0]}],"extra":1})");
    EXPECT_NE(e.find("extra"), std::string::npos) << e;
    e = parseError(R"({"version":1,"handles":[{"nodes":[0]}],)");
    EXPECT_NE(e.find("invalid JSON"), std::string::npos) << e;
    e = parseError(R"({"version":1,"handles":[{"box":{"min":[0,0,0],"max":[1,1,1]},"nodes":[0]}]})");
    EXPECT_NE(e.find("exactly one selection"), std::string::npos) << e;
    e = parseError(R"({"version":1,"handles":[{"nodes":[0],"fixed":true,"translate":[1,0,0]}]})");
    EXPECT_NE(e.find("fixed"), std::string::npos) << e;
}

TEST(DeformSpec, EmptySelectionAndReassignment)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{1000, 1});
    const DeformationGraph g = DeformationGraph::build(rest, GraphOptions{32, 6, 0});
    const DeformSpec empty = parseDeformSpec(
        R"({"version":1,"units":"bbox","handles":[{"nodes":[0]},{"sphere":{"center":[5,5,5],"radius":0.01}}]})", "e.json");
    const std::string e = inputError([&] { resolveHandles(empty, g, rest); });
    EXPECT_NE(e.find("e.json: handle 1"), std::string::npos) << e;
    EXPECT_NE(e.find("selects no graph node"), std::string::npos) << e;
    const DeformSpec range = parseDeformSpec(R"({"version":1,"handles":[{"nodes":[999]}]})", "r.json");
    EXPECT_NE(inputError([&] { resolveHandles(range, g, rest); }).find("r.json: handle 0"), std::string::npos);

    const DeformSpec twice = parseDeformSpec(
        R"({"version":1,"handles":[{"nodes":[0,1,2],"fixed":true},{"nodes":[2,3],"translate":[0,1,0]}]})", "t.json");
    const HandleResolution h = resolveHandles(twice, g, rest);
    ASSERT_EQ(h.reassignments.size(), 1u);
    EXPECT_EQ(h.reassignments[0].node, 2);
    EXPECT_EQ(h.reassignments[0].fromHandle, 0);
    EXPECT_EQ(h.reassignments[0].toHandle, 1);
    EXPECT_EQ(h.nodesPerHandle, (std::vector<std::size_t>{2, 2}));
    EXPECT_EQ(h.constraints.fixed[2], 0);
    EXPECT_EQ(h.constraints.hasTarget[2], 1);
    EXPECT_DOUBLE_EQ(h.constraints.target[3].y, g.nodes()[3].y + 1.0);
}

TEST(DeformSpec, BboxUnitsAndTargets)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{1000, 1});
    const DeformationGraph g = DeformationGraph::build(rest, GraphOptions{32, 6, 0});
    Vec3f lo, hi;
    centreBounds(rest, lo, hi);
    // Node 5 scaled by 2 about a bbox pivot, rotated 90 degrees about z, translated by 10% of the extent.
    const DeformSpec s = parseDeformSpec(R"({"version":1,"units":"bbox","handles":[{"nodes":[5],"scale":2,
        "rotate":{"axis":[0,0,1],"degrees":90},"pivot":[0.5,0.5,0.5],"translate":[0.1,0,0]}]})", "b.json");
    const HandleResolution h = resolveHandles(s, g, rest);
    const Vec3d pivot = (Vec3d(lo) + Vec3d(hi)) * 0.5;
    const Vec3d d = (g.nodes()[5] - pivot) * 2.0;
    const Vec3d expect = pivot + Vec3d(-d.y, d.x, d.z) + Vec3d(0.1 * (hi.x - lo.x), 0, 0);
    EXPECT_NEAR(length(h.constraints.target[5] - expect), 0.0, 1e-12);
}
