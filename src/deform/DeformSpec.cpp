#include "deform/DeformSpec.h"

#include <cmath>
#include <nlohmann/json.hpp>
#include <set>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "io/JsonText.h"

namespace splatwarp {

namespace {

using json = nlohmann::json;

/// Error context: "<file>: handle 2: " or "<file>: ".
struct Where {
    std::string prefix;
    [[noreturn]] void fail(const std::string& what) const { throw InputError(prefix + what); }
};

/// obj must be an object with only `allowed` keys and every `required` one.
void checkKeys(const json& obj, const std::set<std::string>& allowed, const std::string& what, const Where& w,
               const std::vector<std::string>& required = {})
{
    if (!obj.is_object()) w.fail(msg(what, " must be a JSON object"));
    for (const std::string& r : required)
        if (!obj.contains(r)) w.fail(msg(what, " needs \"", r, "\""));
    for (auto it = obj.begin(); it != obj.end(); ++it)
        if (!allowed.count(it.key())) {
            std::string list;
            for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
            w.fail(msg("unknown key \"", it.key(), "\" in ", what, " (allowed: ", list, ")"));
        }
}

double number(const json& v, const std::string& what, const Where& w)
{
    if (!v.is_number()) w.fail(msg(what, " must be a number"));
    const double d = v.get<double>();
    if (!std::isfinite(d)) w.fail(msg(what, " is not a finite number"));
    return d;
}

Vec3d vec3(const json& v, const std::string& what, const Where& w)
{
    if (!v.is_array() || v.size() != 3) w.fail(msg(what, " must be an array of 3 numbers"));
    return {number(v[0], what + "[0]", w), number(v[1], what + "[1]", w), number(v[2], what + "[2]", w)};
}

int integer(const json& v, const std::string& what, const Where& w, long lo, long hi)
{
    if (!v.is_number_integer()) w.fail(msg(what, " must be an integer"));
    const long long x = v.get<long long>();
    if (x < lo || x > hi) w.fail(msg(what, " = ", x, " is outside ", lo, "..", hi));
    return int(x);
}

HandleSpec parseHandle(const json& h, const Where& w)
{
    checkKeys(h, {"box", "sphere", "nodes", "fixed", "scale", "rotate", "pivot", "translate"}, "the handle", w);
    HandleSpec s;
    const int selections = int(h.contains("box")) + int(h.contains("sphere")) + int(h.contains("nodes"));
    if (selections != 1) w.fail("needs exactly one selection: \"box\", \"sphere\" or \"nodes\"");
    if (h.contains("box")) {
        const json& b = h["box"];
        checkKeys(b, {"min", "max"}, "\"box\"", w, {"min", "max"});
        s.select = HandleSpec::Select::Box;
        s.boxMin = vec3(b["min"], "box.min", w);
        s.boxMax = vec3(b["max"], "box.max", w);
        for (int a = 0; a < 3; ++a)
            if (s.boxMin[a] > s.boxMax[a]) w.fail(msg("box.min[", a, "] > box.max[", a, "]"));
    } else if (h.contains("sphere")) {
        const json& b = h["sphere"];
        checkKeys(b, {"center", "radius"}, "\"sphere\"", w, {"center", "radius"});
        s.select = HandleSpec::Select::Sphere;
        s.centre = vec3(b["center"], "sphere.center", w);
        s.radius = number(b["radius"], "sphere.radius", w);
        if (!(s.radius > 0)) w.fail("sphere.radius must be > 0");
    } else {
        const json& n = h["nodes"];
        if (!n.is_array() || n.empty()) w.fail("\"nodes\" must be a non-empty array of node indices");
        s.select = HandleSpec::Select::Nodes;
        for (const json& v : n) s.nodes.push_back(integer(v, "node index", w, 0, 1L << 30));
    }
    if (h.contains("fixed")) {
        if (!h["fixed"].is_boolean()) w.fail("\"fixed\" must be true or false");
        s.fixed = h["fixed"].get<bool>();
    }
    if (s.fixed)
        for (const char* k : {"scale", "rotate", "pivot", "translate"})
            if (h.contains(k)) w.fail(msg("a fixed handle cannot have \"", k, "\""));
    if (h.contains("scale")) {
        s.scale = number(h["scale"], "scale", w);
        if (!(s.scale > 0)) w.fail("scale must be > 0");
    }
    if (h.contains("rotate")) {
        const json& r = h["rotate"];
        checkKeys(r, {"axis", "degrees"}, "\"rotate\"", w, {"axis", "degrees"});
        s.axis = unitVector(vec3(r["axis"], "rotate.axis", w));
        if (!(length(s.axis) > 0)) w.fail("rotate.axis is the zero vector");
        s.degrees = number(r["degrees"], "rotate.degrees", w);
    }
    if (h.contains("pivot")) {
        s.hasPivot = true;
        s.pivot = vec3(h["pivot"], "pivot", w);
    }
    if (h.contains("translate")) s.translate = vec3(h["translate"], "translate", w);
    return s;
}

} // namespace

DeformSpec parseDeformSpec(const std::string& jsonText, const std::string& sourceName)
{
    DeformSpec spec;
    spec.source = sourceName;
    const Where top{sourceName + ": "};
    // Follow the parse so a syntax error (NaN, overflowing numbers ...) can name the handle it is in.
    std::string key;
    bool inHandles = false;
    int handle = -1;
    auto follow = [&](int depth, json::parse_event_t ev, json& parsed) {
        if (depth == 1 && ev == json::parse_event_t::key) key = parsed.get<std::string>();
        if (depth == 1 && ev == json::parse_event_t::array_start) inHandles = key == "handles";
        if (depth == 1 && ev == json::parse_event_t::array_end) inHandles = false;
        if (depth == 2 && inHandles && ev == json::parse_event_t::object_start) ++handle;
        return true;
    };
    json root;
    try {
        root = parseJsonFollowing(follow, jsonText);
    } catch (const json::exception& e) {
        const std::string where = inHandles && handle >= 0 ? msg("handle ", handle, ": ") : std::string();
        top.fail(msg(where, "invalid JSON (NaN/Infinity and overflowing numbers are not allowed): ", e.what()));
    }
    checkKeys(root, {"version", "units", "graph", "handles"}, "the spec", top);
    if (!root.contains("version")) top.fail("missing \"version\" (expected 1)");
    if (!root["version"].is_number_integer() || root["version"].get<long long>() != 1)
        top.fail(msg("unsupported \"version\" ", root["version"].dump(), " (expected 1)"));
    if (root.contains("units")) {
        const json& u = root["units"];
        if (u == "world") spec.units = DeformSpec::Units::World;
        else if (u == "bbox") spec.units = DeformSpec::Units::Bbox;
        else top.fail(msg("\"units\" must be \"world\" or \"bbox\" (got ", u.dump(), ")"));
    }
    if (root.contains("graph")) {
        const json& g = root["graph"];
        checkKeys(g, {"nodes", "k", "seed"}, "\"graph\"", top);
        if (g.contains("nodes")) spec.graph.nodes = integer(g["nodes"], "graph.nodes", top, 1, 1L << 20);
        if (g.contains("k")) spec.graph.k = integer(g["k"], "graph.k", top, 1, 64);
        if (g.contains("seed")) spec.graph.seed = std::uint32_t(integer(g["seed"], "graph.seed", top, 0, 0x7fffffffL));
    }
    if (!root.contains("handles") || !root["handles"].is_array() || root["handles"].empty())
        top.fail("\"handles\" must be a non-empty array");
    const json& hs = root["handles"];
    for (std::size_t i = 0; i < hs.size(); ++i)
        spec.handles.push_back(parseHandle(hs[i], Where{msg(sourceName, ": handle ", i, ": ")}));
    return spec;
}

DeformSpec loadDeformSpec(const std::string& path)
{
    return parseDeformSpec(readWholeFile(path, "deformation spec file"), path);
}

} // namespace splatwarp
