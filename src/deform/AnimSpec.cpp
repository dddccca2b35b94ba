#include "deform/AnimSpec.h"

#include <cmath>

#include "core/Error.h"
#include "io/JsonText.h"

namespace splatwarp {

namespace {

using json = nlohmann::json;

const char* const kMotionFields[] = {"rotate", "translate", "scale", "pivot"};

[[noreturn]] void fail(const std::string& where, const std::string& what) { throw InputError(where + what); }

double finiteNumber(const json& v, const std::string& what, const std::string& where)
{
    if (!v.is_number() || !std::isfinite(v.get<double>())) fail(where, what + " must be a finite number");
    return v.get<double>();
}

Vec3d vec3(const json& v, const std::string& what, const std::string& where)
{
    if (!v.is_array() || v.size() != 3) fail(where, what + " must be an array of 3 numbers");
    return {finiteNumber(v[0], what, where), finiteNumber(v[1], what, where), finiteNumber(v[2], what, where)};
}

Quatd axisAngleQuat(const Vec3d& axis, double degrees)
{
    const double half = degrees * M_PI / 360.0, s = std::sin(half); // axis: a unit vector
    return {std::cos(half), axis.x * s, axis.y * s, axis.z * s};
}

bool readSmooth(const json& obj, bool inherited, const std::string& where)
{
    if (!obj.contains("ease")) return inherited;
    const json& e = obj["ease"];
    if (e != "smooth" && e != "linear") fail(where, msg("\"ease\" must be \"smooth\" or \"linear\" (got ", e.dump(), ")"));
    return e == "smooth";
}

/// A key's numbers from its motion fields (shape checks only; parseDeformSpec checks the rest).
MotionKey readKey(int frame, const json& motion, const std::string& where)
{
    MotionKey k;
    k.frame = frame;
    k.motion = motion;
    if (motion.contains("rotate")) {
        const json& r = motion["rotate"];
        if (!r.is_object() || !r.contains("axis") || !r.contains("degrees"))
            fail(where, "\"rotate\" needs \"axis\" and \"degrees\"");
        const Vec3d axis = unitVector(vec3(r["axis"], "rotate.axis", where)); // as parseDeformSpec
        if (!(length(axis) > 0)) fail(where, "rotate.axis is the zero vector");
        k.hasRotate = true;
        k.axis = axis;
        k.degrees = finiteNumber(r["degrees"], "rotate.degrees", where);
        k.rotation = axisAngleQuat(axis, k.degrees);
    }
    if (motion.contains("translate")) k.translate = vec3(motion["translate"], "translate", where);
    if (motion.contains("scale")) k.scale = finiteNumber(motion["scale"], "scale", where);
    if (motion.contains("pivot")) {
        k.hasPivot = true;
        k.pivot = vec3(motion["pivot"], "pivot", where);
    }
    return k;
}

/// The keys of one handle; `handle` loses its motion fields (they move into the keys).
MotionTrack readTrack(json& handle, int frames, bool smooth, const std::string& where)
{
    MotionTrack track;
    track.smooth = readSmooth(handle, smooth, where);
    handle.erase("ease");
    json motion = json::object();
    for (const char* f : kMotionFields)
        if (handle.contains(f)) motion[f] = handle[f];
    const bool fixed = handle.contains("fixed") && handle["fixed"] == true;
    if (!handle.contains("keys")) {
        if (fixed || motion.empty()) return track; // static: the handle is emitted as written
        // A plain motion ramps from rest at frame 0 to the motion at the last frame.
        json rest = json::object();
        if (motion.contains("pivot")) rest["pivot"] = motion["pivot"];
        if (frames > 1) track.keys.push_back(readKey(0, rest, where));
        track.keys.push_back(readKey(frames - 1, motion, where));
    } else {
        if (fixed) fail(where, "a fixed handle cannot have \"keys\"");
        for (const char* f : kMotionFields)
            if (f != std::string("pivot") && handle.contains(f))
                fail(where, msg("\"", f, "\" belongs in the keys when the handle has \"keys\""));
        const json& keys = handle["keys"];
        if (!keys.is_array() || keys.empty()) fail(where, "\"keys\" must be a non-empty array");
        for (std::size_t i = 0; i < keys.size(); ++i) {
            const std::string kw = msg(where, "key ", i, ": ");
            const json& key = keys[i];
            if (!key.is_object() || !key.contains("frame") || !key["frame"].is_number_integer())
                fail(kw, "needs an integer \"frame\"");
            const long long f = key["frame"].get<long long>();
            if (f < 0 || f >= frames) fail(kw, msg("frame ", f, " is outside 0..", frames - 1, " (\"frames\": ", frames, ")"));
            if (!track.keys.empty() && f <= track.keys.back().frame)
                fail(kw, msg("frame ", f, " does not follow frame ", track.keys.back().frame, " (keys must be in increasing frame order)"));
            json m = key;
            m.erase("frame");
            for (auto it = m.begin(); it != m.end(); ++it)
                if (it.key() != "rotate" && it.key() != "translate" && it.key() != "scale" && it.key() != "pivot")
                    fail(kw, msg("unknown key \"", it.key(), "\" (allowed: frame, rotate, translate, scale, pivot)"));
            if (!m.contains("pivot") && motion.contains("pivot")) m["pivot"] = motion["pivot"];
            track.keys.push_back(readKey(int(f), m, kw));
        }
        handle.erase("keys");
    }
    for (const char* f : kMotionFields) handle.erase(f);
    for (std::size_t i = 1; i < track.keys.size(); ++i)
        if (track.keys[i].hasPivot != track.keys[0].hasPivot)
            fail(where, "give \"pivot\" in every key or in none (the centroid pivot cannot be interpolated with a given one)");
    return track;
}

Vec3d lerp(const Vec3d& a, const Vec3d& b, double t) { return a + (b - a) * t; }

json vecJson(const Vec3d& v) { return json::array({v.x, v.y, v.z}); }

/// Keys a and b as turns about one axis (`axis`, angles `da`, `db`): a key without a rotation
/// turns 0 about the other's axis; an axis written reversed turns the other way. False when the
/// axes differ.
bool sharedAxis(const MotionKey& a, const MotionKey& b, Vec3d& axis, double& da, double& db)
{
    axis = a.hasRotate ? a.axis : b.hasRotate ? b.axis : Vec3d(0, 0, 1);
    da = a.degrees;
    db = b.degrees;
    if (!a.hasRotate || !b.hasRotate) return true;
    const double c = dot(a.axis, b.axis);
    if (c < -1.0 + 1e-12) db = -db;
    return std::fabs(c) > 1.0 - 1e-12;
}

/// The rotate field between keys a and b at t (none for no turn).
void rotateBetween(const MotionKey& a, const MotionKey& b, double t, json& m)
{
    Vec3d axis;
    double da = 0, db = 0;
    if (sharedAxis(a, b, axis, da, db)) { // the angle as written: 0 -> 720 turns twice, 0 -> 400 turns 400
        const double degrees = da + (db - da) * t;
        if (degrees != 0.0) m["rotate"] = {{"axis", vecJson(axis)}, {"degrees", degrees}};
        return;
    }
    const Quatd q = slerp(a.rotation, b.rotation, t);
    const double sinHalf = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z);
    if (sinHalf > 0.0) {
        m["rotate"] = {{"axis", vecJson(Vec3d(q.x, q.y, q.z) / sinHalf)},
                       {"degrees", 2.0 * std::atan2(sinHalf, q.w) * 180.0 / M_PI}};
    }
}

/// Why keys a and b cannot be interpolated, or "": slerp between different axes follows neither
/// key's full turns, and is undefined between opposite quaternions.
std::string unreachableTurn(const MotionKey& a, const MotionKey& b)
{
    Vec3d axis;
    double da = 0, db = 0;
    if (sharedAxis(a, b, axis, da, db)) return "";
    if (std::fabs(a.degrees) >= 360.0 || std::fabs(b.degrees) >= 360.0)
        return "keys about different axes are slerped, which cannot follow a turn of 360 degrees or more "
               "(give both keys one axis, or add a key in between)";
    const Quatd &p = a.rotation, &q = b.rotation;
    if (p.w * q.w + p.x * q.x + p.y * q.y + p.z * q.z < -1.0 + 1e-12)
        return "its rotation is 360 degrees from the previous key's (add a key in between)";
    return "";
}

/// The motion fields of a track at a frame: a key's own fields at (or beyond) it, else interpolated.
json motionAt(const MotionTrack& track, int frame)
{
    const std::vector<MotionKey>& keys = track.keys;
    if (frame <= keys.front().frame) return keys.front().motion;
    if (frame >= keys.back().frame) return keys.back().motion;
    std::size_t i = 1;
    while (keys[i].frame < frame) ++i;
    const MotionKey &a = keys[i - 1], &b = keys[i];
    if (b.frame == frame) return b.motion;
    double t = double(frame - a.frame) / double(b.frame - a.frame);
    if (track.smooth) t = smoothEase(t);
    json m = json::object();
    rotateBetween(a, b, t, m);
    m["translate"] = vecJson(lerp(a.translate, b.translate, t));
    m["scale"] = a.scale + (b.scale - a.scale) * t;
    if (a.hasPivot) m["pivot"] = vecJson(lerp(a.pivot, b.pivot, t));
    return m;
}

} // namespace

double smoothEase(double t) { return t * t * (3.0 - 2.0 * t); }

Quatd slerp(const Quatd& a, const Quatd& b, double t)
{
    const double dot = a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
    if (dot < -1.0 + 1e-12) throw InputError("slerp between opposite quaternions (rotations 360 degrees apart) is undefined");
    double wa = 1.0 - t, wb = t;
    if (dot < 1.0 - 1e-12) {
        const double theta = std::acos(dot), s = std::sin(theta);
        wa = std::sin((1.0 - t) * theta) / s;
        wb = std::sin(t * theta) / s;
    }
    Quatd q{wa * a.w + wb * b.w, wa * a.x + wb * b.x, wa * a.y + wb * b.y, wa * a.z + wb * b.z};
    const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
    return {q.w / n, q.x / n, q.y / n, q.z / n};
}

AnimSpec parseAnimSpec(const std::string& jsonText, const std::string& sourceName)
{
    AnimSpec anim;
    anim.source = sourceName;
    const std::string top = sourceName + ": ";
    json root;
    try {
        root = parseJson(jsonText);
    } catch (const json::exception& e) {
        fail(top, msg("invalid JSON: ", e.what()));
    }
    if (!root.is_object()) fail(top, "the spec must be a JSON object");
    if (!root.contains("frames")) fail(top, "missing \"frames\" (the number of frames to animate)");
    const json& frames = root["frames"];
    if (!frames.is_number_integer() || frames.get<long long>() <= 0 || frames.get<long long>() > 1000000)
        fail(top, msg("\"frames\" must be an integer in 1..1000000 (got ", frames.dump(), ")"));
    anim.frames = int(frames.get<long long>());
    const bool smooth = readSmooth(root, false, top);
    root.erase("frames");
    root.erase("ease");
    if (!root.contains("handles") || !root["handles"].is_array() || root["handles"].empty())
        fail(top, "\"handles\" must be a non-empty array");
    for (std::size_t h = 0; h < root["handles"].size(); ++h) {
        json& handle = root["handles"][h];
        if (!handle.is_object()) fail(msg(top, "handle ", h, ": "), "the handle must be a JSON object");
        anim.tracks.push_back(readTrack(handle, anim.frames, smooth, msg(top, "handle ", h, ": ")));
    }
    anim.base = std::move(root);
    // Every key as written must be a valid plain spec (same checks and messages as `deform`);
    // between keys the rotation must be one that can be followed (unreachableTurn()).
    for (std::size_t h = 0; h < anim.tracks.size(); ++h) {
        const std::vector<MotionKey>& keys = anim.tracks[h].keys;
        for (std::size_t i = 0; i < keys.size(); ++i) {
            frameSpec(anim, keys[i].frame);
            const std::string why = i > 0 ? unreachableTurn(keys[i - 1], keys[i]) : "";
            if (!why.empty()) fail(msg(top, "handle ", h, ": key ", i, ": "), why);
        }
    }
    return anim;
}

json frameSpecJson(const AnimSpec& anim, int frame)
{
    if (frame < 0 || frame >= anim.frames)
        throw InputError(msg(anim.source, ": frame ", frame, " is outside 0..", anim.frames - 1));
    json spec = anim.base;
    for (std::size_t h = 0; h < anim.tracks.size(); ++h) {
        if (anim.tracks[h].keys.empty()) continue;
        const json motion = motionAt(anim.tracks[h], frame);
        for (auto it = motion.begin(); it != motion.end(); ++it) spec["handles"][h][it.key()] = it.value();
    }
    return spec;
}

DeformSpec frameSpec(const AnimSpec& anim, int frame)
{
    return parseDeformSpec(frameSpecJson(anim, frame).dump(), msg(anim.source, " (frame ", frame, ")"));
}

} // namespace splatwarp
