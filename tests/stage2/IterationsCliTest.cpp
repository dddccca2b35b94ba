// `--iterations N|auto` on the command line (deform; animate and batch take the same flag).
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "stage2/StageTwoOptions.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

TEST(IterationsCli, TakesAutoAndWholeNumbersAndRefusesOtherWords)
{
    TempDir dir;
    DemoModelOptions so;
    so.count = 2000;
    writePly(dir.file("in.ply"), makeDemoModel("stripes", so));
    const std::string base = "-q deform " + dir.file("in.ply") + " --spec " + std::string(SPLATWARP_SOURCE_DIR) +
                             "/samples/specs/bend.json --nodes 48 --cells 16 --samples-per-cell 4 --no-eval --eval-points 5000 --device cpu ";
    for (const char* bad : {"sometimes", "-3", "2.5", "10x", "", "AUTO"})
        EXPECT_EQ(runCli(base + "--stage1-only --iterations '" + std::string(bad) + "' -o " + dir.file("bad")), 2) << bad;
    auto stage2 = [&](const std::string& flags, const std::string& name) {
        const std::string out = dir.file(name);
        EXPECT_EQ(runCli(base + flags + " -o " + out), 0) << flags;
        std::ifstream in(out + "/report.json");
        return nlohmann::json::parse(in)["stage2"];
    };
    const nlohmann::json three = stage2("--iterations 3", "three");
    EXPECT_EQ(three["parameters"]["iterations"].get<int>(), 3);
    EXPECT_EQ(three["stoppedAt"].get<int>(), -1);
    EXPECT_EQ(three["energies"].back()["iteration"].get<int>(), 3);
    // auto: the cap, and a stall stop; a --stall-tolerance given too keeps its value whatever the
    // order (0.5: stops long before the cap, as no 10 iterations halve the energy 29 times in a row).
    const nlohmann::json a = stage2("--iterations auto --stall-tolerance 0.5", "auto-a");
    const nlohmann::json b = stage2("--stall-tolerance 0.5 --iterations auto", "auto-b");
    EXPECT_EQ(a["parameters"]["iterations"].get<int>(), StageTwoOptions::kAutoIterations);
    EXPECT_GT(a["stoppedAt"].get<int>(), 0);
    EXPECT_LT(a["stoppedAt"].get<int>(), StageTwoOptions::kAutoIterations);
    EXPECT_EQ(b["stoppedAt"].get<int>(), a["stoppedAt"].get<int>());
    EXPECT_EQ(b["bestEnergy"].get<double>(), a["bestEnergy"].get<double>());
}
