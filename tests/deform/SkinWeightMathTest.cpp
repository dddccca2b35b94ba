// The brute-force skin weights of the GPU (deform/SkinWeightMath.h), run here as a host loop
// over flat arrays in the GPU layout, against DeformationGraph::skinWeights (nanoflann).
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "deform/DeformationGraph.h"
#include "deform/SkinWeightMath.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

namespace {

/// Brute-force weights of points [P,3] in the GPU layout (nodes as flat doubles [J,3]).
SkinWeights bruteWeights(const DeformationGraph& graph, const std::vector<float>& points)
{
    std::vector<double> flat;
    for (const Vec3d& g : graph.nodes()) flat.insert(flat.end(), {g.x, g.y, g.z});
    SkinWeights w;
    w.k = std::min(graph.k(), int(graph.nodeCount()));
    const std::size_t count = points.size() / 3, k = std::size_t(w.k);
    w.nodes.resize(count * k);
    w.weights.resize(count * k);
    for (std::size_t p = 0; p < count; ++p)
        skinWeightsBrute(flat.data(), graph.nodeCount(), k, points.data(), p, w.nodes.data(), w.weights.data());
    return w;
}

} // namespace

TEST(SkinWeightMath, BruteForceMatchesNanoflann)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{4000, 2});
    for (int k : {1, 4, 8}) {
        const DeformationGraph graph = DeformationGraph::build(rest, GraphOptions{96, k, 0});
        std::mt19937 rng(11);
        std::uniform_real_distribution<float> u(-2.5f, 2.5f);
        std::vector<float> points(3 * 5000);
        for (float& x : points) x = u(rng);
        const SkinWeights ref = graph.skinWeights(points.data(), points.size() / 3);
        const SkinWeights got = bruteWeights(graph, points);
        ASSERT_EQ(got.k, ref.k);
        // Random points are spread (skinWeights() searches them in Morton order, each run near
        // its nodes). Random float points have no exact distance ties, so the node lists agree
        // exactly; the squared distances are computed the same way in double (dx^2 + dy^2 + dz^2),
        // so the weights are identical too.
        EXPECT_EQ(got.nodes, ref.nodes) << "k " << k;
        EXPECT_EQ(got.weights, ref.weights) << "k " << k;
    }
}

// Points in runs of neighbours (a sample cell's samples, as warpSamples() passes them), where
// skinWeights() searches only the nodes near each run, and runs spread over the model, where it
// searches the tree: both give the brute force's nodes and weights exactly.
TEST(SkinWeightMath, RunsOfNeighboursMatchTheBruteForce)
{
    const GaussianCloud rest = makeDemoModel("stripes", DemoModelOptions{4000, 2});
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-2.0f, 2.0f), cell(0.0f, 0.08f);
    std::vector<float> points;
    for (int c = 0; c < 60; ++c) { // 60 cells of 100 samples, then 700 scattered points
        const float x = u(rng), y = u(rng) * 0.3f, z = u(rng) * 0.3f;
        for (int s = 0; s < 100; ++s) points.insert(points.end(), {x + cell(rng), y + cell(rng), z + cell(rng)});
    }
    for (int s = 0; s < 700; ++s) points.insert(points.end(), {u(rng), u(rng), u(rng)});
    for (int k : {1, 4, 8}) {
        const DeformationGraph graph = DeformationGraph::build(rest, GraphOptions{256, k, 0});
        const SkinWeights got = graph.skinWeights(points.data(), points.size() / 3);
        const SkinWeights serial = graph.skinWeights(points.data(), points.size() / 3, false);
        const SkinWeights ref = bruteWeights(graph, points);
        EXPECT_EQ(got.nodes, ref.nodes) << "k " << k;
        EXPECT_EQ(got.weights, ref.weights) << "k " << k;
        EXPECT_EQ(serial.nodes, got.nodes);
        EXPECT_EQ(serial.weights, got.weights);
    }
}

TEST(SkinWeightMath, DegenerateCasesAndTies)
{
    // Two nodes, k 8: d_{k+1} is twice the farther node's distance (the documented fallback).
    const DeformationGraph two = DeformationGraph::fromNodes({Vec3d(0, 0, 0), Vec3d(1, 0, 0)}, 8);
    const std::vector<float> p = {0.25f, 0.0f, 0.0f};
    const SkinWeights ref = two.skinWeights(p.data(), 1), got = bruteWeights(two, p);
    EXPECT_EQ(got.nodes, ref.nodes);
    EXPECT_EQ(got.weights, ref.weights);
    // Hand-derived: d = 0.25, 0.75, dNext = 1.5: w ~ (5/6)^2, (1/2)^2 normalised.
    const double a = 25.0 / 36.0, b = 0.25;
    EXPECT_FLOAT_EQ(got.weights[0], float(a / (a + b)));
    // Equidistant nodes: the tie goes to the lower index, the weights are uniform (all zero raw).
    const DeformationGraph square = DeformationGraph::fromNodes(
        {Vec3d(1, 0, 0), Vec3d(-1, 0, 0), Vec3d(0, 1, 0), Vec3d(0, -1, 0)}, 2);
    const std::vector<float> centre = {0.0f, 0.0f, 0.0f};
    const SkinWeights tie = bruteWeights(square, centre);
    EXPECT_EQ(tie.nodes, (std::vector<std::int32_t>{0, 1}));
    EXPECT_EQ(tie.weights, (std::vector<float>{0.5f, 0.5f}));
}
