// --max-gaussians: the budget every step that adds Gaussians spends (issue 33).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "core/GaussianBudget.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

TEST(GaussianBudget, ParsesCountsAndFactorsAndRefusesTheRest)
{
    GaussianBudget b;
    EXPECT_EQ(parseGaussianBudget("250000", b), "");
    EXPECT_EQ(b.limit(1000), 250000u);
    EXPECT_EQ(parseGaussianBudget("1.5x", b), "");
    EXPECT_EQ(b.limit(1001), 1501u); // floor(1.5 x 1001)
    EXPECT_EQ(b.added(1001), 500u);
    EXPECT_EQ(b.text(), "1.5x");
    EXPECT_EQ(parseGaussianBudget("2\u00d7", b), "");
    EXPECT_EQ(b.limit(7), 14u);
    EXPECT_EQ(parseGaussianBudget("1x", b), "");
    EXPECT_EQ(b.added(12345), 0u);
    for (const char* bad : {"", "0", "-1", "abc", "1.5y", "0.5x", "1.5", "x", "1e3", "2000x"})
        EXPECT_NE(parseGaussianBudget(bad, b), "") << bad;
    EXPECT_EQ(parseGaussianBudget("900", b), "");
    EXPECT_THROW(b.limit(1000), UsageError); // below the input: nothing removes Gaussians to meet it
}

namespace {

std::size_t countOf(const std::string& ply) { return readGaussians(ply).size(); }

nlohmann::json reportOf(const std::string& dir)
{
    std::ifstream in(dir + "/report.json");
    return nlohmann::json::parse(in);
}

} // namespace

TEST(GaussianBudget, DeformHonoursTheBudgetAndOneTimesKeepsTheCount)
{
    TempDir dir;
    const std::string model = dir.file("s.ply"), spec = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json";
    ASSERT_EQ(runCli("-q sample stripes --count 2000 -o " + model), 0);
    const std::string common = "-q deform " + model + " --spec " + spec + " --iterations 4 " + kQuickDeform;
    // Without a budget the splits add more than 300 here, so a budget of 2300 binds.
    ASSERT_EQ(runCli(common + "-o " + dir.file("free") + " --max-gaussians none"), 0);
    const std::size_t free = countOf(dir.file("free/deformed.ply"));
    ASSERT_GT(free, 2300u);
    ASSERT_EQ(runCli(common + "-o " + dir.file("b2300") + " --max-gaussians 2300"), 0);
    const std::size_t bounded = countOf(dir.file("b2300/deformed.ply"));
    EXPECT_LE(bounded, 2300u);
    EXPECT_GT(bounded, 2000u);
    const nlohmann::json r = reportOf(dir.file("b2300"));
    EXPECT_EQ(r["stage2"]["gaussianBudget"].get<std::size_t>(), 2300u);
    EXPECT_EQ(r["stage2"]["gaussians"].get<std::size_t>(), bounded);
    EXPECT_EQ(r["stage2"]["gaussiansAdded"].get<std::size_t>() - r["stage2"]["gaussiansRemoved"].get<std::size_t>(), bounded - 2000);
    // The budget is met after the fit: the splits added their own share, the merge removed the rest.
    EXPECT_GT(r["curveSplit"]["added"].get<std::size_t>(), 300u);
    EXPECT_EQ(r["stage2"]["budgetMerge"]["removed"].get<std::size_t>(), r["stage2"]["gaussiansRemoved"].get<std::size_t>());
    EXPECT_EQ(r["stage2"]["budgetMerge"]["limit"].get<std::size_t>(), 2300u);
    EXPECT_TRUE(r["settings"]["budgetMerge"].get<bool>());
    // --budget-merge off: the splits spend the budget itself, nothing is merged.
    ASSERT_EQ(runCli(common + "-o " + dir.file("nomerge") + " --max-gaussians 2300 --budget-merge off"), 0);
    const nlohmann::json off = reportOf(dir.file("nomerge"));
    EXPECT_LE(countOf(dir.file("nomerge/deformed.ply")), 2300u);
    EXPECT_LE(off["curveSplit"]["added"].get<std::size_t>(), 300u);
    EXPECT_FALSE(off["stage2"].contains("budgetMerge"));
    // 1x with the keep: nothing is split (splitting all and merging all back judges worse), nothing merged.
    ASSERT_EQ(runCli(common + "-o " + dir.file("onekeep") + " --max-gaussians 1x"), 0);
    const nlohmann::json onekeep = reportOf(dir.file("onekeep"));
    EXPECT_EQ(countOf(dir.file("onekeep/deformed.ply")), 2000u);
    EXPECT_EQ(onekeep["curveSplit"]["added"].get<std::size_t>(), 0u);
    EXPECT_FALSE(onekeep["stage2"].contains("budgetMerge"));
    // 1x: no step adds a Gaussian, Stage II's own split included (its fit kept, so a split would show).
    ASSERT_EQ(runCli(common + "-o " + dir.file("one") + " --max-gaussians 1x --split auto --split-stretch 1.01 --keep fit"), 0);
    EXPECT_EQ(countOf(dir.file("one/deformed.ply")), 2000u);
    EXPECT_EQ(reportOf(dir.file("one"))["stage2"]["gaussiansAdded"].get<std::size_t>(), 0u);
    // Without the budget that split does add Gaussians (so the line above tests the budget).
    ASSERT_EQ(runCli(common + "-o " + dir.file("split") +
                     " --curve-split off --validated-split off --split auto --split-stretch 1.01 --keep fit"),
              0);
    EXPECT_GT(countOf(dir.file("split/deformed.ply")), 2000u);
}

// --curve-split-prune: at 1x the curve split still splits by removing the faintest Gaussians, and the
// report counts both.
TEST(GaussianBudget, AtOneTimesTheCurveSplitMakesRoomByRemovingTheFaintest)
{
    TempDir dir;
    const std::string model = dir.file("s.ply"), spec = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json";
    ASSERT_EQ(runCli("-q sample stripes --count 2000 -o " + model), 0);
    // A model with faint specks, as captures have: every fourth Gaussian at alpha 0.01, a third its size.
    GaussianCloud specked = readGaussians(model);
    for (std::size_t i = 0; i < specked.size(); i += 4) {
        specked.opacities[i] = std::log(0.01f / 0.99f);
        for (int a = 0; a < 3; ++a) specked.logScales[3 * i + std::size_t(a)] += std::log(1.0f / 3.0f);
    }
    writePly(dir.file("specked.ply"), specked);
    const std::string common =
        "-q deform " + dir.file("specked.ply") + " --spec " + spec + " --iterations 4 --max-gaussians 1x --keep fit " + kQuickDeform;
    ASSERT_EQ(runCli(common + "-o " + dir.file("one") + " --curve-split-prune 3"), 0);
    const nlohmann::json one = reportOf(dir.file("one"));
    EXPECT_EQ(countOf(dir.file("one/deformed.ply")), 2000u);
    const std::size_t added = one["curveSplit"]["added"].get<std::size_t>(), pruned = one["curveSplit"]["pruned"].get<std::size_t>();
    EXPECT_GT(added, 0u); // the split was made at no growth
    EXPECT_EQ(pruned, added);
    EXPECT_EQ(one["stage2"]["gaussiansAdded"].get<std::size_t>(), added);
    EXPECT_EQ(one["stage2"]["gaussiansRemoved"].get<std::size_t>(), pruned);
    EXPECT_EQ(one["settings"]["curveSplitPrune"].get<double>(), 3.0);
    // Without the prune (the default) nothing is split at 1x, so the lines above test it.
    ASSERT_EQ(runCli(common + "-o " + dir.file("noprune")), 0);
    EXPECT_EQ(reportOf(dir.file("noprune"))["curveSplit"]["added"].get<std::size_t>(), 0u);
    EXPECT_EQ(reportOf(dir.file("noprune"))["curveSplit"]["pruned"].get<std::size_t>(), 0u);
}

TEST(GaussianBudget, BadBudgetsExitTwoAndWriteNothing)
{
    TempDir dir;
    const std::string model = dir.file("s.ply"), spec = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/bend.json";
    ASSERT_EQ(runCli("-q sample stripes --count 500 -o " + model), 0);
    for (const char* bad : {"0", "abc", "0.5x", "-3", "400"}) {
        const std::string out = dir.file(std::string("bad-") + bad);
        EXPECT_EQ(runCli("-q deform " + model + " --spec " + spec + " -o " + out + " --max-gaussians " + bad, dir.file("e.log")), 2) << bad;
        EXPECT_FALSE(std::filesystem::exists(out)) << bad;
        EXPECT_NE(fileBytes(dir.file("e.log")).find("--max-gaussians"), std::string::npos) << fileBytes(dir.file("e.log"));
    }
    EXPECT_NE(fileBytes(dir.file("e.log")).find("below the input's 500 Gaussians"), std::string::npos) << fileBytes(dir.file("e.log"));
}
