/// Graphdeco PLY reader: properties found by name, so order, missing normals, extra properties,
/// extra elements, ASCII, big-endian and non-float types all load.
#include <set>

#include "core/Error.h"
#include "io/FormatReaders.h"

namespace splatwarp {

GaussianCloud readGraphdecoPly(const std::string& path, const PlyHeader& header, const PlyBody& body,
                               ReadReport& report)
{
    if (!header.find("vertex")) throw InputError(msg(path, ": PLY has no 'vertex' element"));
    const PlyElementValues& v = body.element("vertex");
    const PlyElement& e = v.element();

    // f_rest_0..M-1 with M = 3((d+1)^2 - 1) fixes the degree.
    std::size_t restCount = 0;
    for (const PlyProperty& p : e.properties)
        if (p.name.compare(0, 7, "f_rest_") == 0) ++restCount;
    int degree = -1;
    for (int d = 0; d <= 3; ++d)
        if (restCount == std::size_t(3 * (shCoeffCount(d) - 1))) degree = d;
    if (degree < 0)
        throw InputError(msg(path, ": element 'vertex' has ", restCount,
                             " f_rest_* properties; expected 0, 9, 24 or 45 (SH degree 0..3)"));
    const int k = shCoeffCount(degree);

    // Column of every value a Gaussian needs, in graphdeco order (normals excluded).
    std::vector<std::string> wanted;
    for (const std::string& name : graphdecoPropertyNames(degree))
        if (name != "nx" && name != "ny" && name != "nz") wanted.push_back(name);
    std::vector<int> col(wanted.size());
    std::string missing;
    for (std::size_t i = 0; i < wanted.size(); ++i) {
        col[i] = e.find(wanted[i]);
        if (col[i] < 0) missing += (missing.empty() ? "" : ", ") + wanted[i];
    }
    if (!missing.empty())
        throw InputError(msg(path, ": element 'vertex' lacks required properties: ", missing));

    const std::set<std::string> known(wanted.begin(), wanted.end());
    for (const PlyProperty& p : e.properties)
        if (!known.count(p.name) && p.name != "nx" && p.name != "ny" && p.name != "nz")
            report.notes.push_back(msg("ignored extra property '", p.name, "' of element 'vertex'"));
    for (const std::string& note : skippedElementNotes(header, {"vertex"})) report.notes.push_back(note);

    GaussianCloud g;
    g.resize(e.count, degree);
    for (std::size_t i = 0; i < e.count; ++i) {
        std::size_t c = 0;
        const auto next = [&] { return float(v.get(i, col[c++])); };
        for (int a = 0; a < 3; ++a) g.means[3 * i + a] = next();
        float* sh = g.shOf(i);
        for (int ch = 0; ch < 3; ++ch) sh[ch] = next();
        for (int ch = 0; ch < 3; ++ch) // channel-major f_rest: R block, then G, then B
            for (int j = 1; j < k; ++j) sh[3 * j + ch] = next();
        g.opacities[i] = next();
        for (int a = 0; a < 3; ++a) g.logScales[3 * i + a] = next();
        for (int a = 0; a < 4; ++a) g.rotations[4 * i + a] = next();
    }
    report.format = header.formatName();
    return g;
}

} // namespace splatwarp
