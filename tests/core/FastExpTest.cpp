// fastExp against std::exp in double over its whole range.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/FastExp.h"

using namespace splatwarp;

namespace {
// Worst relative error measured over the grid below: 8.0e-8 (under one float ulp).
constexpr double kRel = 1.2e-7;
} // namespace

TEST(FastExp, MatchesExpOverItsRange)
{
    double worst = 0;
    for (int i = 0; i <= 2000000; ++i) {
        const float x = -87.0f + 175.0f * float(i) / 2000000.0f;
        const double ref = std::exp(double(x));
        const double rel = std::fabs(double(fastExp(x)) - ref) / ref;
        worst = std::max(worst, rel);
    }
    std::printf("  worst relative error %.3g\n", worst);
    EXPECT_LT(worst, kRel);
}

TEST(FastExp, ExactAtZeroAndClampedOutside)
{
    EXPECT_EQ(fastExp(0.0f), 1.0f);
    EXPECT_EQ(fastExp(-1000.0f), fastExp(-87.0f));
    EXPECT_GT(fastExp(-87.0f), 0.0f);
    EXPECT_TRUE(std::isfinite(fastExp(1000.0f)));
    EXPECT_EQ(fastExp(std::numeric_limits<float>::quiet_NaN()), fastExp(-87.0f)); // never UB, never NaN
    EXPECT_EQ(expOf(0.5), std::exp(0.5));                                          // double keeps std::exp
}
