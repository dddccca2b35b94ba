#include <gtest/gtest.h>

#include <cmath>

#include "deform/AnimSpec.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using splatwarp::test::inputErrorMessage;
using json = nlohmann::json;

namespace {

const char* kFixed = R"({"box":{"min":[0,0,0],"max":[0.1,1,1]},"fixed":true})";

/// A keyframed spec: a fixed handle and a moving one with the given keys (and extra fields).
std::string animText(int frames, const std::string& keys, const std::string& extraTop = "")
{
    return std::string(R"({"version":1,"units":"bbox","frames":)") + std::to_string(frames) + extraTop +
           R"(,"handles":[)" + kFixed + R"(,{"box":{"min":[0.9,0,0],"max":[1,1,1]},"pivot":[0.5,1,0.5],"keys":)" + keys +
           "}]}";
}

const std::string kKeys = R"([{"frame":0},
   {"frame":4,"rotate":{"axis":[0,0,1],"degrees":90},"translate":[0,0.2,0],"scale":1.5},
   {"frame":8,"rotate":{"axis":[0,0,3],"degrees":0}}])";

json moving(const AnimSpec& a, int f) { return frameSpecJson(a, f)["handles"][1]; }

double angleDeg(const Quatd& q) { return 2.0 * std::acos(std::min(1.0, std::fabs(q.w))) * 180.0 / M_PI; }

Quatd axisAngle(Vec3d axis, double deg)
{
    const double h = deg * M_PI / 360.0, n = length(axis);
    return {std::cos(h), axis.x / n * std::sin(h), axis.y / n * std::sin(h), axis.z / n * std::sin(h)};
}

std::string parseError(const std::string& text)
{
    return inputErrorMessage([&] { parseAnimSpec(text, "anim.json"); });
}

} // namespace

TEST(AnimSpec, KeyFramesReproduceTheKeysExactly)
{
    const AnimSpec a = parseAnimSpec(animText(9, kKeys), "anim.json");
    ASSERT_EQ(a.frames, 9);
    const json k4 = moving(a, 4);
    EXPECT_EQ(k4["rotate"], json::parse(R"({"axis":[0,0,1],"degrees":90})"));
    EXPECT_EQ(k4["scale"], 1.5);
    EXPECT_EQ(k4["translate"], json::parse("[0,0.2,0]"));
    EXPECT_EQ(k4["pivot"], json::parse("[0.5,1,0.5]"));
    EXPECT_FALSE(moving(a, 0).contains("rotate")); // the rest key: no motion at all
    EXPECT_EQ(moving(a, 8)["rotate"]["axis"], json::parse("[0,0,3]")); // as written, not normalised
    EXPECT_FALSE(moving(a, 4).contains("keys"));
    EXPECT_FALSE(frameSpecJson(a, 4).contains("frames"));
    EXPECT_EQ(frameSpecJson(a, 4)["handles"][0], json::parse(kFixed)); // static handles pass through
}

TEST(AnimSpec, LinearBetweenKeysForTranslateScaleAndAngle)
{
    const AnimSpec a = parseAnimSpec(animText(9, kKeys), "anim.json");
    const json m = moving(a, 1); // t = 1/4 from rest to key 4
    EXPECT_NEAR(m["scale"].get<double>(), 1.125, 1e-12);
    EXPECT_NEAR(m["translate"][1].get<double>(), 0.05, 1e-12);
    EXPECT_NEAR(m["rotate"]["degrees"].get<double>(), 22.5, 1e-9); // same axis: slerp = linear angle
    EXPECT_NEAR(m["rotate"]["axis"][2].get<double>(), 1.0, 1e-12);
    EXPECT_NEAR(moving(a, 6)["rotate"]["degrees"].get<double>(), 45.0, 1e-9); // halfway back to 0
    // The result is a plain spec that `deform` accepts.
    const DeformSpec s = frameSpec(a, 6);
    EXPECT_NEAR(s.handles[1].degrees, 45.0, 1e-9);
}

TEST(AnimSpec, SlerpHasConstantSpeedUnitLengthAndFollowsTheWrittenArc)
{
    const Quatd a = axisAngle({1, 2, 3}, 10), b = axisAngle({-2, 0.5, 1}, 130);
    const double total = [&] {
        const double d = a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
        return 2.0 * std::acos(d) * 180.0 / M_PI;
    }();
    for (double t : {0.0, 0.2, 0.5, 0.9, 1.0}) {
        const Quatd q = slerp(a, b, t);
        EXPECT_NEAR(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z, 1.0, 1e-12);
        // The relative rotation a^-1 q has angle t * total (constant angular speed).
        const Quatd rel{a.w * q.w + a.x * q.x + a.y * q.y + a.z * q.z, 0, 0, 0};
        EXPECT_NEAR(angleDeg(rel), t * total, 1e-7) << t;
    }
    // 0 -> 270 degrees about z turns through 135 at the midpoint (no shortest-path flip to -90).
    const Quatd mid = slerp(axisAngle({0, 0, 1}, 0), axisAngle({0, 0, 1}, 270), 0.5);
    EXPECT_NEAR(2.0 * std::atan2(mid.z, mid.w) * 180.0 / M_PI, 135.0, 1e-9);
    EXPECT_FALSE(inputErrorMessage([] { slerp(axisAngle({0, 0, 1}, 0), axisAngle({0, 0, 1}, 360), 0.5); }).empty());
}

TEST(AnimSpec, SmoothEaseIsSymmetricWithFlatEnds)
{
    EXPECT_EQ(smoothEase(0.0), 0.0);
    EXPECT_EQ(smoothEase(1.0), 1.0);
    EXPECT_DOUBLE_EQ(smoothEase(0.5), 0.5);
    for (double t : {0.1, 0.25, 0.4}) EXPECT_NEAR(smoothEase(t) + smoothEase(1 - t), 1.0, 1e-15);
    EXPECT_LT(smoothEase(0.01), 0.01 * 0.01 * 3.0 + 1e-12); // zero slope at 0
    const AnimSpec a = parseAnimSpec(animText(9, kKeys, R"(,"ease":"smooth")"), "anim.json");
    EXPECT_NEAR(moving(a, 1)["scale"].get<double>(), 1.0 + 0.5 * smoothEase(0.25), 1e-12);
    EXPECT_NEAR(moving(a, 2)["rotate"]["degrees"].get<double>(), 45.0, 1e-9); // midpoint unchanged
}

TEST(AnimSpec, PlainSpecWithFramesRampsFromRest)
{
    const std::string plain = std::string(R"({"version":1,"units":"bbox","frames":5,"handles":[)") + kFixed +
                              R"(,{"box":{"min":[0.9,0,0],"max":[1,1,1]},"rotate":{"axis":[0,0,1],"degrees":80},"pivot":[0.5,1,0.5]}]})";
    const AnimSpec a = parseAnimSpec(plain, "plain.json");
    json expectLast = json::parse(plain);
    expectLast.erase("frames");
    EXPECT_EQ(frameSpecJson(a, 4), expectLast); // the last frame is the plain spec itself
    EXPECT_FALSE(moving(a, 0).contains("rotate"));
    EXPECT_EQ(moving(a, 0)["pivot"], json::parse("[0.5,1,0.5]"));
    EXPECT_NEAR(moving(a, 2)["rotate"]["degrees"].get<double>(), 40.0, 1e-9);
}

TEST(AnimSpec, HoldsBeforeTheFirstAndAfterTheLastKey)
{
    const AnimSpec a = parseAnimSpec(animText(12, R"([{"frame":3,"translate":[0,1,0]},{"frame":6,"translate":[0,2,0]}])"), "a.json");
    EXPECT_EQ(moving(a, 0)["translate"], json::parse("[0,1,0]"));
    EXPECT_EQ(moving(a, 11)["translate"], json::parse("[0,2,0]"));
}

TEST(AnimSpec, RefusesBadFramesAndKeys)
{
    EXPECT_NE(parseError(animText(0, kKeys)).find("\"frames\" must be an integer in 1.."), std::string::npos);
    EXPECT_NE(parseError(animText(-3, kKeys)).find("frames"), std::string::npos);
    EXPECT_NE(parseError(R"({"version":1,"handles":[{"nodes":[0],"translate":[0,1,0]}]})").find("missing \"frames\""),
              std::string::npos);
    const std::string out = parseError(animText(8, kKeys));
    EXPECT_NE(out.find("anim.json: handle 1: key 2: frame 8 is outside 0..7"), std::string::npos) << out;
    const std::string unordered = parseError(animText(9, R"([{"frame":4},{"frame":2}])"));
    EXPECT_NE(unordered.find("handle 1: key 1: frame 2 does not follow frame 4"), std::string::npos) << unordered;
    EXPECT_NE(parseError(animText(9, R"([{"frame":1},{"frame":1}])")).find("does not follow"), std::string::npos);
    EXPECT_NE(parseError(animText(9, R"([{"frame":1,"spin":3}])")).find("unknown key \"spin\""), std::string::npos);
    EXPECT_NE(parseError(animText(9, R"([{"frame":1,"rotate":{"axis":[0,0,0],"degrees":3}}])")).find("zero vector"),
              std::string::npos);
    // |[1e200, 0, 0]| overflowed: as in a plain spec, any magnitude is a unit axis.
    const AnimSpec huge = parseAnimSpec(animText(9, R"([{"frame":2,"rotate":{"axis":[1e200,0,0],"degrees":30}}])"), "anim.json");
    const DeformSpec between = parseDeformSpec(frameSpecJson(huge, 1).dump(), "frame 1");
    EXPECT_EQ(between.handles[1].axis.x, 1.0);
    EXPECT_GT(between.handles[1].degrees, 0.0);
    // About one axis 0 -> 360 is a full turn (AnimSpec.TurnsAboutOneAxisFollowTheAngleAsWritten); about two it has no arc.
    EXPECT_NE(parseError(animText(9, R"([{"frame":0,"rotate":{"axis":[1,0,0],"degrees":10}},{"frame":2,"rotate":{"axis":[0,0,1],"degrees":360}}])"))
                  .find("cannot follow a turn of 360 degrees"),
              std::string::npos);
    EXPECT_NE(parseError(animText(9, R"([{"frame":0,"scale":-1}])")).find("scale must be > 0"), std::string::npos);
    EXPECT_NE(parseError(animText(9, kKeys, R"(,"ease":"bouncy")")).find("\"ease\" must be"), std::string::npos);
    const std::string keysOnFixed = std::string(R"({"version":1,"frames":3,"handles":[{"nodes":[0],"fixed":true,"keys":[{"frame":0}]}]})");
    EXPECT_NE(parseError(keysOnFixed).find("a fixed handle cannot have \"keys\""), std::string::npos);
}

TEST(AnimSpec, TurnsAboutOneAxisFollowTheAngleAsWritten)
{
    // Slerp between the keys' quaternions lost whole turns: 720 did not move, 540 turned -180, 400 the wrong way.
    for (double d : {720.0, 540.0, 400.0, 270.0, -450.0}) {
        const std::string keys = R"([{"frame":0},{"frame":4,"rotate":{"axis":[0,0,1],"degrees":)" + std::to_string(d) + "}}]";
        const AnimSpec a = parseAnimSpec(animText(5, keys), "anim.json");
        for (int f = 1; f <= 4; ++f) {
            const json r = moving(a, f)["rotate"];
            EXPECT_NEAR(r["degrees"].get<double>(), d * f / 4.0, 1e-9) << d << " frame " << f;
            EXPECT_NEAR(r["axis"][2].get<double>(), 1.0, 1e-12) << d << " frame " << f;
        }
    }
    // An axis written reversed is the same axis turning the other way: 90 about z -> 90 about -z passes 0.
    const AnimSpec back = parseAnimSpec(
        animText(5, R"([{"frame":0,"rotate":{"axis":[0,0,1],"degrees":90}},{"frame":4,"rotate":{"axis":[0,0,-2],"degrees":90}}])"), "anim.json");
    EXPECT_FALSE(moving(back, 2).contains("rotate"));
    EXPECT_NEAR(moving(back, 3)["rotate"]["degrees"].get<double>(), -45.0, 1e-9);
}
