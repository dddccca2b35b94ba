#include "deform/NodeTransforms.h"

namespace splatwarp {

NodeTransforms NodeTransforms::identity(std::size_t n)
{
    NodeTransforms x;
    x.A.assign(n, Mat3d::identity());
    x.t.assign(n, Vec3d(0, 0, 0));
    return x;
}

Vec3d skinPoint(const DeformationGraph& graph, const NodeTransforms& transforms, const SkinWeights& weights,
                std::size_t i, const Vec3d& v)
{
    const std::size_t k = std::size_t(weights.k);
    const std::vector<Vec3d>& g = graph.nodes();
    Vec3d out(0, 0, 0);
    double sum = 0.0;
    for (std::size_t a = 0; a < k; ++a) {
        const double w = double(weights.weights[i * k + a]);
        if (w == 0.0) continue;
        const std::size_t j = std::size_t(weights.nodes[i * k + a]);
        out += (transforms.A[j] * (v - g[j]) + g[j] + transforms.t[j]) * w;
        sum += w;
    }
    // Divide by the sum of the float weights (1 up to rounding) so rigid motions stay exact in double.
    return out / sum;
}

Mat3d skinGradient(const DeformationGraph&, const NodeTransforms& transforms, const SkinWeights& weights, std::size_t i)
{
    const std::size_t k = std::size_t(weights.k);
    Mat3d out;
    double sum = 0.0;
    for (std::size_t a = 0; a < k; ++a) {
        const double w = double(weights.weights[i * k + a]);
        if (w == 0.0) continue;
        out = out + transforms.A[std::size_t(weights.nodes[i * k + a])] * w;
        sum += w;
    }
    return out * (1.0 / sum);
}

std::vector<NodeAffine> nodeAffines(const DeformationGraph& graph, const NodeTransforms& x)
{
    std::vector<NodeAffine> nodes(graph.nodeCount());
    for (std::size_t j = 0; j < nodes.size(); ++j) {
        const Vec3d& g = graph.nodes()[j];
        const Vec3d b = g + x.t[j] - x.A[j] * g;
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) nodes[j].a[r][c] = x.A[j][r][c];
            nodes[j].b[r] = b[r];
        }
    }
    return nodes;
}

AffineSkinning::AffineSkinning(const DeformationGraph& graph, const NodeTransforms& x) : mNodes(nodeAffines(graph, x)) {}

Vec3d AffineSkinning::point(const SkinWeights& w, std::size_t q, const Vec3d& v) const
{
    return skinAffinePoint(mNodes.data(), w.nodes.data(), w.weights.data(), std::size_t(w.k), q, v);
}

Mat3d AffineSkinning::gradient(const SkinWeights& w, std::size_t q) const
{
    return skinAffineGradient(mNodes.data(), w.nodes.data(), w.weights.data(), std::size_t(w.k), q);
}

} // namespace splatwarp
