/// The glTF node graph of a `.glb`: which nodes instantiate which mesh, with what global transform
/// (glTF 2.0 section 3.5: column-major `matrix` or T * R * S, parent times child), and applying a
/// transform to splats (KHR_gaussian_splatting: the node matrix must decompose into translation,
/// rotation and positive scale; we take a uniform one, which a Gaussian can follow exactly).
#include "io/GltfNodes.h"

#include <algorithm>
#include <cmath>

#include "core/Error.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

using nlohmann::json;

double number(const std::string& path, const json& v)
{
    if (!v.is_number()) throw InputError(msg(path, ": .glb: a node transform holds a value that is not a number"));
    return v.get<double>();
}

NodeTransform localTransform(const std::string& path, const json& node)
{
    NodeTransform t;
    if (node.contains("matrix")) {
        const json& m = node["matrix"];
        if (!m.is_array() || m.size() != 16) throw InputError(msg(path, ": .glb: a node matrix without 16 numbers"));
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) t.m[r][c] = number(path, m[std::size_t(4 * c + r)]); // column-major
            t.t[r] = number(path, m[std::size_t(12 + r)]);
        }
        return t;
    }
    const auto vec = [&](const char* key, std::size_t n, std::vector<double> d) {
        if (!node.contains(key)) return d;
        if (!node[key].is_array() || node[key].size() != n)
            throw InputError(msg(path, ": .glb: node '", key, "' without ", n, " numbers"));
        for (std::size_t k = 0; k < n; ++k) d[k] = number(path, node[key][k]);
        return d;
    };
    const std::vector<double> tr = vec("translation", 3, {0, 0, 0}), q = vec("rotation", 4, {0, 0, 0, 1}),
                              s = vec("scale", 3, {1, 1, 1});
    const Mat3d r = quatToMatrix(Quatd{q[3], q[0], q[1], q[2]});
    for (int a = 0; a < 3; ++a) {
        for (int c = 0; c < 3; ++c) t.m[a][c] = r[a][c] * s[std::size_t(c)];
        t.t[a] = tr[std::size_t(a)];
    }
    return t;
}

// Deeper node chains are refused: the walk recurses (a crafted chain must not exhaust the stack).
constexpr int kMaxNodeDepth = 256;

void visit(const std::string& path, const json& nodes, std::size_t index, const NodeTransform& parent, int depth,
           std::vector<int>& seen, std::vector<MeshInstance>& out)
{
    if (depth > kMaxNodeDepth) throw InputError(msg(path, ": .glb: node hierarchy deeper than ", kMaxNodeDepth));
    if (index >= nodes.size() || !nodes[index].is_object())
        throw InputError(msg(path, ": .glb: node ", index, " does not exist"));
    if (seen[index]++) throw InputError(msg(path, ": .glb: node ", index, " is reached twice (the node graph must be a forest)"));
    const json& node = nodes[index];
    const NodeTransform local = localTransform(path, node);
    NodeTransform global;
    global.m = parent.m * local.m;
    global.t = parent.m * local.t + parent.t;
    if (node.contains("mesh")) {
        if (!node["mesh"].is_number_unsigned()) throw InputError(msg(path, ": .glb: node ", index, ": bad mesh index"));
        out.push_back({node["mesh"].get<std::size_t>(), global});
    }
    if (node.contains("children") && node["children"].is_array())
        for (const json& c : node["children"]) {
            if (!c.is_number_unsigned()) throw InputError(msg(path, ": .glb: node ", index, ": bad child index"));
            visit(path, nodes, c.get<std::size_t>(), global, depth + 1, seen, out);
        }
}

} // namespace

std::vector<MeshInstance> meshInstances(const std::string& path, const json& doc)
{
    std::vector<MeshInstance> out;
    if (!doc.contains("nodes") || !doc["nodes"].is_array()) return out;
    const json& nodes = doc["nodes"];
    std::vector<std::size_t> roots;
    const std::size_t scene = doc.contains("scene") && doc["scene"].is_number_unsigned() ? doc["scene"].get<std::size_t>() : 0;
    if (doc.contains("scenes") && doc["scenes"].is_array() && scene < doc["scenes"].size() &&
        doc["scenes"][scene].contains("nodes") && doc["scenes"][scene]["nodes"].is_array()) {
        for (const json& r : doc["scenes"][scene]["nodes"])
            if (r.is_number_unsigned()) roots.push_back(r.get<std::size_t>());
    } else { // no scene: every node that is nobody's child is a root
        std::vector<int> child(nodes.size(), 0);
        for (const json& n : nodes)
            if (n.is_object() && n.contains("children") && n["children"].is_array())
                for (const json& c : n["children"])
                    if (c.is_number_unsigned() && c.get<std::size_t>() < nodes.size()) child[c.get<std::size_t>()] = 1;
        for (std::size_t i = 0; i < nodes.size(); ++i)
            if (!child[i]) roots.push_back(i);
    }
    std::vector<int> seen(nodes.size(), 0);
    for (std::size_t r : roots) visit(path, nodes, r, NodeTransform{}, 0, seen, out);
    return out;
}

void applyNodeTransform(const std::string& path, const NodeTransform& t, GaussianCloud& g)
{
    double len[3];
    for (int c = 0; c < 3; ++c) len[c] = std::sqrt(t.m[0][c] * t.m[0][c] + t.m[1][c] * t.m[1][c] + t.m[2][c] * t.m[2][c]);
    const double s = (len[0] + len[1] + len[2]) / 3;
    const Mat3d r = t.m * (1 / s);
    const Mat3d rtr = r.transposed() * r;
    double off = 0;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) off = std::max(off, std::fabs(rtr[a][b] - (a == b ? 1.0 : 0.0)));
    if (!(s > 0 && std::isfinite(s)) || off > 1e-5 || r.determinant() < 0)
        throw InputError(msg(path, ": .glb: a node transform of splats that is not a rotation times a uniform positive "
                                   "scale (column lengths ", len[0], ", ", len[1], ", ", len[2], ", determinant ",
                                   t.m.determinant(), ") is not supported"));
    const float logS = float(std::log(s));
    for (std::size_t i = 0; i < g.size(); ++i) {
        g.setMean(i, Vec3f(t.m * Vec3d(g.mean(i)) + t.t));
        for (int a = 0; a < 3; ++a) g.logScales[3 * i + a] += logS;
        const Quatf q = g.rotation(i);
        const Quatd nq = matrixToQuat(r * quatToMatrix(Quatd{q.w, q.x, q.y, q.z}));
        g.setRotation(i, Quatf{float(nq.w), float(nq.x), float(nq.y), float(nq.z)});
    }
    rotateCloudSh(g, r);
}

} // namespace splatwarp
