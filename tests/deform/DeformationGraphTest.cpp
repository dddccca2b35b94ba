#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "core/Error.h"
#include "deform/DeformationGraph.h"
#include "deform/NodeTransforms.h"
#include "demo/DemoModels.h"

using namespace splatwarp;

namespace {

GaussianCloud randomCloud(std::size_t n, std::uint32_t seed)
{
    GaussianCloud g;
    g.resize(n, 0);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    for (float& v : g.means) v = u(rng);
    return g;
}

double dist(const Vec3d& a, const Vec3d& b) { return length(a - b); }

} // namespace

TEST(DeformationGraph, FpsIsDeterministicSerialEqualsParallelAndSpreads)
{
    const GaussianCloud g = randomCloud(20000, 3);
    const GraphOptions o{64, 8, 5};
    const DeformationGraph a = DeformationGraph::build(g, o, true);
    const DeformationGraph b = DeformationGraph::build(g, o, false);
    ASSERT_EQ(a.nodeCount(), 64u);
    ASSERT_EQ(b.nodeCount(), 64u);
    for (std::size_t j = 0; j < a.nodeCount(); ++j) {
        EXPECT_EQ(a.nodes()[j].x, b.nodes()[j].x);
        EXPECT_EQ(a.nodes()[j].y, b.nodes()[j].y);
        EXPECT_EQ(a.nodes()[j].z, b.nodes()[j].z);
    }
    // FPS property (naive reference): node j is the centre farthest from nodes 0..j-1.
    for (std::size_t j = 1; j < 6; ++j) {
        double best = -1.0;
        for (std::size_t i = 0; i < g.size(); ++i) {
            double m = 1e300;
            for (std::size_t q = 0; q < j; ++q) m = std::min(m, dist(Vec3d(g.mean(i)), a.nodes()[q]));
            best = std::max(best, m);
        }
        double mine = 1e300;
        for (std::size_t q = 0; q < j; ++q) mine = std::min(mine, dist(a.nodes()[j], a.nodes()[q]));
        EXPECT_NEAR(mine, best, 1e-6) << "node " << j;
    }
}

TEST(DeformationGraph, EdgesAreTheKNearestOtherNodes)
{
    const DeformationGraph gr = DeformationGraph::build(randomCloud(5000, 4), GraphOptions{40, 6, 0});
    const auto& n = gr.nodes();
    for (std::size_t j = 0; j < gr.nodeCount(); ++j) {
        std::vector<std::size_t> order(gr.nodeCount());
        std::iota(order.begin(), order.end(), 0);
        order.erase(order.begin() + j);
        std::sort(order.begin(), order.end(), [&](auto a, auto b) { return dist(n[a], n[j]) < dist(n[b], n[j]); });
        const auto& e = gr.neighbours(j);
        ASSERT_EQ(e.size(), 6u);
        for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(dist(n[std::size_t(e[i])], n[j]), dist(n[order[i]], n[j]), 1e-12);
    }
}

TEST(DeformationGraph, WeightsNonNegativeSumToOneLocalAndMatchFormula)
{
    const DeformationGraph gr = DeformationGraph::build(randomCloud(5000, 5), GraphOptions{50, 8, 1});
    const GaussianCloud q = randomCloud(300, 6);
    const SkinWeights w = gr.skinWeights(q.means.data(), q.size(), true);
    const SkinWeights ws = gr.skinWeights(q.means.data(), q.size(), false);
    ASSERT_EQ(w.k, 8);
    ASSERT_EQ(w.size(), q.size());
    EXPECT_EQ(w.nodes, ws.nodes);
    EXPECT_EQ(w.weights, ws.weights);
    const auto& n = gr.nodes();
    for (std::size_t p = 0; p < q.size(); ++p) {
        const Vec3d v(q.mean(p));
        // Naive reference: sort all nodes by distance.
        std::vector<std::size_t> order(gr.nodeCount());
        std::iota(order.begin(), order.end(), 0);
        std::sort(order.begin(), order.end(), [&](auto a, auto b) { return dist(n[a], v) < dist(n[b], v); });
        const double dNext = dist(n[order[8]], v);
        double sum = 0.0, refSum = 0.0;
        for (int i = 0; i < 8; ++i) refSum += std::pow(1.0 - dist(n[order[i]], v) / dNext, 2.0);
        for (int i = 0; i < 8; ++i) {
            const float wi = w.weights[p * 8 + i];
            EXPECT_GE(wi, 0.0f);
            sum += wi;
            const std::size_t node = std::size_t(w.nodes[p * 8 + i]);
            EXPECT_NEAR(dist(n[node], v), dist(n[order[i]], v), 1e-12); // locality: the i-th nearest
            EXPECT_NEAR(wi, std::pow(1.0 - dist(n[node], v) / dNext, 2.0) / refSum, 1e-6);
        }
        EXPECT_NEAR(sum, 1.0, 1e-6);
    }
}

TEST(DeformationGraph, DegenerateInputs)
{
    // Fewer distinct points than nodes, with duplicates: stops at the distinct count.
    GaussianCloud g;
    g.resize(10, 0);
    for (std::size_t i = 0; i < 10; ++i) g.setMean(i, Vec3f(float(i % 3), 0.0f, 0.0f));
    const DeformationGraph gr = DeformationGraph::build(g, GraphOptions{256, 8, 0});
    EXPECT_EQ(gr.nodeCount(), 3u);
    EXPECT_EQ(gr.neighbours(0).size(), 2u);
    const SkinWeights w = gr.skinWeights(g.means.data(), g.size());
    EXPECT_EQ(w.k, 3);
    for (std::size_t p = 0; p < w.size(); ++p) {
        double s = 0.0;
        for (int i = 0; i < 3; ++i) {
            EXPECT_TRUE(std::isfinite(w.weights[p * 3 + i]));
            EXPECT_GE(w.weights[p * 3 + i], 0.0f);
            s += w.weights[p * 3 + i];
        }
        EXPECT_NEAR(s, 1.0, 1e-6);
    }
    // All centres identical: one node, d_{k+1} == 0 -> weight 1.
    GaussianCloud same;
    same.resize(5, 0);
    const DeformationGraph one = DeformationGraph::build(same, GraphOptions{});
    EXPECT_EQ(one.nodeCount(), 1u);
    const SkinWeights w1 = one.skinWeights(same.means.data(), same.size());
    for (float x : w1.weights) EXPECT_EQ(x, 1.0f);
    // Coincident nodes (fromNodes): d_{k+1} == 0 at a node -> uniform, finite.
    const DeformationGraph dup = DeformationGraph::fromNodes({Vec3d(0, 0, 0), Vec3d(0, 0, 0), Vec3d(0, 0, 0)}, 2);
    const float origin[3] = {0, 0, 0};
    const SkinWeights wd = dup.skinWeights(origin, 1);
    EXPECT_FLOAT_EQ(wd.weights[0], 0.5f);
    EXPECT_FLOAT_EQ(wd.weights[1], 0.5f);
    EXPECT_THROW(DeformationGraph::build(GaussianCloud{}, GraphOptions{}), InputError);
}

TEST(DeformationGraph, SkinningIdentityAndRigid)
{
    const GaussianCloud g = makeDemoModel("stripes", DemoModelOptions{2000, 1});
    const DeformationGraph gr = DeformationGraph::build(g, GraphOptions{32, 8, 0});
    const SkinWeights w = gr.skinWeights(g.means.data(), g.size());
    NodeTransforms x = NodeTransforms::identity(gr.nodeCount());
    const Mat3d r = quatToMatrix(Quatd{0.8, 0.3, -0.4, 0.2});
    const Vec3d tr(0.3, -1.0, 2.0);
    for (std::size_t p = 0; p < g.size(); ++p) {
        const Vec3d v(g.mean(p));
        const Vec3d same = skinPoint(gr, x, w, p, v);
        EXPECT_NEAR(length(same - v), 0.0, 1e-12);
    }
    for (std::size_t j = 0; j < gr.nodeCount(); ++j) {
        x.A[j] = r;
        x.t[j] = r * gr.nodes()[j] + tr - gr.nodes()[j];
    }
    for (std::size_t p = 0; p < g.size(); ++p) {
        const Vec3d v(g.mean(p));
        EXPECT_NEAR(length(skinPoint(gr, x, w, p, v) - (r * v + tr)), 0.0, 1e-12);
        const Mat3d f = skinGradient(gr, x, w, p);
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) EXPECT_NEAR(f[a][b], r[a][b], 1e-14);
    }
}
