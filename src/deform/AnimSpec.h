#pragma once
/// @file AnimSpec.h
/// @brief A keyframed deformation spec: a function frame -> plain spec (`splatwarp
///        animate`). The file is a version-1 spec plus "frames" and optional "ease" at the top and,
///        per moving handle, "keys" [{"frame", "rotate", "translate", "scale", "pivot"}]; a handle
///        without keys ramps from rest (frame 0) to its motion (last frame). Between two keys
///        about one axis (or one key without a rotation) the angle is interpolated as written
///        (0 -> 720 turns twice); about different axes the rotations are slerped (each below 360
///        degrees). The rest is interpolated linearly; key frames reproduce the key exactly.
///        Format: samples/specs/README.md.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/SmallMath.h"
#include "deform/DeformSpec.h"

namespace splatwarp {

/// @brief One key of a handle's motion (the fields a plain handle has).
struct MotionKey {
    int frame = 0;
    Quatd rotation;             ///< unit quaternion of the key's rotate (identity when absent)
    bool hasRotate = false;
    Vec3d axis;                 ///< the rotate's axis, unit length, and its angle as written
    double degrees = 0.0;
    Vec3d translate;
    double scale = 1.0;
    bool hasPivot = false;
    Vec3d pivot;
    nlohmann::json motion;      ///< the key's motion fields as written (emitted verbatim at its frame)
};

/// @brief A handle's keys in increasing frame order; empty for fixed or motionless handles.
struct MotionTrack {
    std::vector<MotionKey> keys;
    bool smooth = false;        ///< "ease": "smooth" (smoothstep between keys)
};

/// @brief A parsed keyframed spec.
struct AnimSpec {
    std::string source = "<spec>";
    int frames = 1;
    nlohmann::json base;              ///< the spec without frames/ease/keys and without handle motions
    std::vector<MotionTrack> tracks;  ///< [handles]
};

/// @brief Parse a keyframed (or plain + "frames") spec. The plain parts are checked as
///        parseDeformSpec() checks them (every key frame's spec is parsed once).
/// @throws InputError naming sourceName (and handle/key): "frames" missing or <= 0, key frames out
///         of 0..frames-1 or not increasing, keys on a fixed handle, motion both in keys and handle.
AnimSpec parseAnimSpec(const std::string& jsonText, const std::string& sourceName);

/// @brief The plain version-1 spec of one frame (0 <= frame < frames), as JSON.
nlohmann::json frameSpecJson(const AnimSpec& anim, int frame);

/// @brief frameSpecJson() parsed by parseDeformSpec() from its text, i.e. exactly what `deform`
///        reads from that text written to a file.
DeformSpec frameSpec(const AnimSpec& anim, int frame);

/// @brief Spherical linear interpolation of unit quaternions along the arc from a to b as written
///        (no shortest-path sign flip, so 0 -> 270 degrees turns 270 degrees).
/// @throws InputError when a and b are opposite (the arc is undefined).
Quatd slerp(const Quatd& a, const Quatd& b, double t);

/// @brief Smoothstep easing 3t^2 - 2t^3 (0 -> 0, 1 -> 1, zero slope at both ends).
double smoothEase(double t);

} // namespace splatwarp
