#pragma once
/// @file PlyTestFiles.h
/// @brief Independent test-side PLY writer with layout variants (ASCII, big-endian, double,
///        integer types, no normals, extra property, extra element, shuffled order) and random
///        clouds, so the reader is checked against files it did not write itself.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "core/GaussianCloud.h"

namespace splatwarp::test {

/// @brief Layout of a test PLY.
struct PlyVariant {
    std::string format = "binary_little_endian"; ///< or "ascii", "binary_big_endian"
    std::string type = "float";                  ///< any PLY scalar type name for every property
    bool normals = true;
    bool extraProperty = false;  ///< an unknown "property <type> foo" in the middle of the record
    bool extraElement = false;   ///< a "face" element with a list property after the vertices
    bool reverseOrder = false;   ///< properties in reverse graphdeco order
};

/// Random cloud: distinct values in every field, unnormalised quaternions.
inline GaussianCloud randomCloud(std::size_t n, int degree, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-2.0f, 2.0f);
    GaussianCloud g;
    g.resize(n, degree);
    for (auto* arr : {&g.means, &g.rotations, &g.logScales, &g.opacities, &g.sh})
        for (float& v : *arr) v = u(rng);
    return g;
}

/// (name, value) of Gaussian i in graphdeco order; f_rest_{c*K'+j-1} = coefficient j of channel c.
inline std::vector<std::pair<std::string, double>> graphdecoRecord(const GaussianCloud& g, std::size_t i, bool normals)
{
    std::vector<std::pair<std::string, double>> r;
    const char* xyz[] = {"x", "y", "z"};
    for (int a = 0; a < 3; ++a) r.push_back({xyz[a], g.means[3 * i + a]});
    if (normals)
        for (const char* nm : {"nx", "ny", "nz"}) r.push_back({nm, 0.0});
    const int k = shCoeffCount(g.shDegree);
    for (int c = 0; c < 3; ++c) r.push_back({"f_dc_" + std::to_string(c), g.sh[i * 3 * k + c]});
    for (int c = 0; c < 3; ++c)
        for (int j = 1; j < k; ++j)
            r.push_back({"f_rest_" + std::to_string(c * (k - 1) + j - 1), g.sh[i * 3 * k + 3 * j + c]});
    r.push_back({"opacity", g.opacities[i]});
    for (int a = 0; a < 3; ++a) r.push_back({"scale_" + std::to_string(a), g.logScales[3 * i + a]});
    for (int a = 0; a < 4; ++a) r.push_back({"rot_" + std::to_string(a), g.rotations[4 * i + a]});
    return r;
}

template <typename T>
void appendScalar(std::string& out, double v, bool bigEndian)
{
    const T t = T(v);
    char b[sizeof(T)];
    std::memcpy(b, &t, sizeof(T));
    if (bigEndian) std::reverse(b, b + sizeof(T));
    out.append(b, sizeof(T));
}

inline void appendValue(std::string& out, const std::string& type, double v, bool ascii, bool bigEndian)
{
    if (ascii) {
        char buf[64];
        std::snprintf(buf, sizeof(buf), "%.17g ", v);
        out += buf;
    } else if (type == "float" || type == "float32") appendScalar<float>(out, v, bigEndian);
    else if (type == "double" || type == "float64") appendScalar<double>(out, v, bigEndian);
    else if (type == "char" || type == "int8") appendScalar<std::int8_t>(out, v, bigEndian);
    else if (type == "uchar" || type == "uint8") appendScalar<std::uint8_t>(out, v, bigEndian);
    else if (type == "short" || type == "int16") appendScalar<std::int16_t>(out, v, bigEndian);
    else if (type == "ushort" || type == "uint16") appendScalar<std::uint16_t>(out, v, bigEndian);
    else if (type == "int" || type == "int32") appendScalar<std::int32_t>(out, v, bigEndian);
    else if (type == "uint" || type == "uint32") appendScalar<std::uint32_t>(out, v, bigEndian);
}

/// @brief The bytes of a PLY holding g in the given layout.
inline std::string plyBytes(const GaussianCloud& g, const PlyVariant& v)
{
    const bool ascii = v.format == "ascii", be = v.format == "binary_big_endian";
    std::vector<std::vector<std::pair<std::string, double>>> recs;
    for (std::size_t i = 0; i < g.size(); ++i) {
        auto r = graphdecoRecord(g, i, v.normals);
        if (v.extraProperty) r.insert(r.begin() + 4, {"foo", 1.0});
        if (v.reverseOrder) std::reverse(r.begin(), r.end());
        recs.push_back(r);
    }
    std::string out = "ply\nformat " + v.format + " 1.0\ncomment written by the splatwarp tests\n";
    out += "element vertex " + std::to_string(g.size()) + "\n";
    const auto names = graphdecoRecord(g.empty() ? randomCloud(1, g.shDegree, 1) : g, 0, v.normals);
    auto header = names;
    if (v.extraProperty) header.insert(header.begin() + 4, {"foo", 1.0});
    if (v.reverseOrder) std::reverse(header.begin(), header.end());
    for (const auto& p : header) out += "property " + v.type + " " + p.first + "\n";
    if (v.extraElement) out += "element face 2\nproperty list uchar int vertex_indices\n";
    out += "end_header\n";
    for (const auto& r : recs) {
        for (const auto& p : r) appendValue(out, v.type, p.second, ascii, be);
        if (ascii) out += "\n";
    }
    if (v.extraElement) {
        for (int f = 0; f < 2; ++f) {
            appendValue(out, "uchar", 3, ascii, be);
            for (int j = 0; j < 3; ++j) appendValue(out, "int", f + j, ascii, be);
            if (ascii) out += "\n";
        }
    }
    return out;
}

/// @brief Write bytes to a file.
inline void writeBytes(const std::string& path, const std::string& bytes)
{
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), std::streamsize(bytes.size()));
}

/// @brief Read a whole file.
inline std::string readBytes(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// @brief Every array of two clouds is bit-identical (NaN patterns included).
inline bool sameBits(const GaussianCloud& a, const GaussianCloud& b)
{
    const auto eq = [](const std::vector<float>& x, const std::vector<float>& y) {
        return x.size() == y.size() && std::memcmp(x.data(), y.data(), x.size() * sizeof(float)) == 0;
    };
    return a.shDegree == b.shDegree && eq(a.means, b.means) && eq(a.rotations, b.rotations) &&
           eq(a.logScales, b.logScales) && eq(a.opacities, b.opacities) && eq(a.sh, b.sh);
}

} // namespace splatwarp::test
