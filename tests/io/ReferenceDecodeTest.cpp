/// .splat and SuperSplat compressed PLY against the same files decoded by an independent tool
/// (PlayCanvas splat-transform), to the formats' quantisation.
#include <gtest/gtest.h>

#include <cmath>

#include "PlyTestFiles.h"
#include "io/GaussianIO.h"
#include "sh/SphericalHarmonics.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

double logitD(double a) { return std::log(a / (1.0 - a)); }

// Largest |component difference| of two quaternions after normalising, up to sign.
double quatDiff(const GaussianCloud& a, const GaussianCloud& b, std::size_t i)
{
    double na = 0, nb = 0, dot = 0;
    for (int k = 0; k < 4; ++k) {
        na += double(a.rotations[4 * i + k]) * a.rotations[4 * i + k];
        nb += double(b.rotations[4 * i + k]) * b.rotations[4 * i + k];
        dot += double(a.rotations[4 * i + k]) * b.rotations[4 * i + k];
    }
    const double s = dot < 0 ? -1.0 : 1.0;
    double worst = 0;
    for (int k = 0; k < 4; ++k)
        worst = std::max(worst, std::abs(a.rotations[4 * i + k] / std::sqrt(na) - s * b.rotations[4 * i + k] / std::sqrt(nb)));
    return worst;
}

} // namespace

TEST(ReferenceDecode, SplatMatchesDecodedPly)
{
    SPLATWARP_REQUIRE_DATA(splat, "splats/lastchance.splat");
    SPLATWARP_REQUIRE_DATA(ref, "splats/lastchance.decoded.ply");
    ReadReport report;
    const GaussianCloud g = readGaussians(splat, {}, &report);
    const GaussianCloud r = readGaussians(ref);
    EXPECT_EQ(report.format, "splat");
    ASSERT_EQ(g.size(), r.size());
    ASSERT_EQ(g.size(), 14831u);

    // Quantisation steps of the u8 fields: colour 1/255 -> f_dc 1/(255 C0); quaternion 1/128
    // per component; alpha 1/255. Scales are float32 in the file: exact in log space up to
    // float rounding of log().
    const double dcStep = 1.0 / (255.0 * kShC0), quatStep = 1.0 / 128.0, alphaStep = 1.0 / 255.0;
    double wPos = 0, wDc = 0, wQuat = 0, wAlpha = 0, wScale = 0;
    for (std::size_t i = 0; i < g.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
            wPos = std::max(wPos, double(std::abs(g.means[3 * i + a] - r.means[3 * i + a])));
            wDc = std::max(wDc, double(std::abs(g.sh[3 * i + a] - r.sh[3 * i + a])));
            const double ls = r.logScales[3 * i + a];
            wScale = std::max(wScale, std::abs(g.logScales[3 * i + a] - ls) / std::max(1.0, std::abs(ls)));
        }
        wQuat = std::max(wQuat, quatDiff(g, r, i));
        wAlpha = std::max(wAlpha, std::abs(sigmoid(double(g.opacities[i])) - sigmoid(double(r.opacities[i]))));
    }
    std::printf("lastchance worst: pos %g  f_dc %g (step %g)  quat %g (step %g)  alpha %g (step %g)  log-scale rel %g\n",
                wPos, wDc, dcStep, wQuat, quatStep, wAlpha, alphaStep, wScale);
    EXPECT_EQ(wPos, 0.0);                 // float32 in both files
    EXPECT_LE(wDc, 0.5 * dcStep);         // same u8 code
    // The reference decodes b/255*2-1 (then normalises), we decode (b-128)/128 as the format's
    // encoder (b = q*128+128) implies: the two differ by up to one code, not half. Measured 0.0059.
    EXPECT_LE(wQuat, quatStep);
    EXPECT_LE(wAlpha, 0.5 * alphaStep);   // same u8 code
    EXPECT_LE(wScale, 2e-7);              // float rounding of log() (2^-23 relative)
}

TEST(ReferenceDecode, CompressedPlyMatchesDecodedPly)
{
    SPLATWARP_REQUIRE_DATA(packed, "splats/guitar.compressed.ply");
    SPLATWARP_REQUIRE_DATA(ref, "splats/guitar.decoded.ply");
    ReadReport report;
    const GaussianCloud g = readGaussians(packed, {}, &report);
    ReadOptions keep;
    keep.keepInvalid = true; // the reference holds +Inf logits where alpha is 255
    const GaussianCloud r = readGaussians(ref, keep);
    EXPECT_EQ(report.format, "ply-compressed");
    ASSERT_EQ(g.size(), r.size());
    ASSERT_EQ(g.size(), 90854u);

    double wPos = 0, wScale = 0, wDc = 0, wQuat = 0, wLogit = 0;
    std::size_t infRef = 0;
    for (std::size_t i = 0; i < g.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
            wPos = std::max(wPos, double(std::abs(g.means[3 * i + a] - r.means[3 * i + a])));
            wScale = std::max(wScale, double(std::abs(g.logScales[3 * i + a] - r.logScales[3 * i + a])));
            wDc = std::max(wDc, double(std::abs(g.sh[3 * i + a] - r.sh[3 * i + a])));
        }
        for (int k = 0; k < 4; ++k)
            wQuat = std::max(wQuat, double(std::abs(g.rotations[4 * i + k] - r.rotations[4 * i + k])));
        if (std::isinf(r.opacities[i])) {
            // alpha code 255: we clamp to a finite logit above the code's lower edge.
            ++infRef;
            EXPECT_GT(r.opacities[i], 0.0f);
            EXPECT_GT(g.opacities[i], logitD(254.5 / 255.0));
            EXPECT_TRUE(std::isfinite(g.opacities[i]));
        } else {
            wLogit = std::max(wLogit, double(std::abs(g.opacities[i] - r.opacities[i])) /
                                          std::max(1.0, std::abs(double(r.opacities[i]))));
        }
    }
    std::printf("guitar worst: pos %g  log-scale %g  f_dc %g  quat %g  logit rel %g  (+Inf in reference: %zu)\n",
                wPos, wScale, wDc, wQuat, wLogit, infRef);
    // Measured worst case: 0 for every field (bit-identical). Both decoders evaluate the same formulas on the same codes and round to float32, so the
    // values agree to float rounding: far below the quantisation steps (position and log-scale
    // step = chunk range / 2047 or / 1023, quaternion sqrt2 / 1023, f_dc 1 / (255 C0)).
    const double f = 1.2e-7; // 2^-23: one float32 rounding relative to the magnitude
    EXPECT_LE(wPos, 4.3 * f * 4);   // |position| <= 4.3 in this model
    EXPECT_LE(wScale, 21.0 * f * 2); // |log-scale| <= ~20
    EXPECT_LE(wDc, 1.8 * f * 2);     // |f_dc| <= 0.5 / C0 = 1.77
    EXPECT_LE(wQuat, f * 2);
    EXPECT_LE(wLogit, f * 2);
    EXPECT_EQ(infRef, 667u);
}
