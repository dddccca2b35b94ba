// Recipes: the pipeline's steps as data. `paper` and `default` are sets of flag values; a recipe
// gives the bytes of those flags, flags given beside it win, a bad recipe names its file.
#include <gtest/gtest.h>

#include <fstream>

#include "job/Recipe.h"
#include "demo/DemoModels.h"
#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

namespace {

using Flags = std::vector<std::pair<std::string, std::string>>;

std::string flagValue(const Flags& flags, const std::string& flag)
{
    std::string v; // the last one wins, as on a command line
    for (const auto& [f, value] : flags)
        if (f == flag) v = value;
    return v;
}

} // namespace

TEST(Recipe, PaperIsPolarStageOneThenStageTwoAndNothingElse)
{
    const Flags paper = recipeFlags(builtinRecipe("paper"));
    EXPECT_EQ(flagValue(paper, "--stage1-shape"), "polar");
    EXPECT_EQ(flagValue(paper, "--boundary-weight"), "99");
    EXPECT_EQ(flagValue(paper, "--iterations"), "100"); // the paper's, not the default's 50
    for (const char* off : {"--curve-split", "--validated-split", "--split"}) EXPECT_EQ(flagValue(paper, off), "off") << off;
    EXPECT_EQ(flagValue(paper, "--curve-shift"), "0");
    EXPECT_EQ(flagValue(paper, "--keep"), "fit");
    const Flags ours = recipeFlags(builtinRecipe("default"));
    for (const char* on : {"--curve-split", "--validated-split", "--curve-shift"}) EXPECT_EQ(flagValue(ours, on), "auto") << on;
    EXPECT_EQ(flagValue(ours, "--keep"), "validated");
    EXPECT_EQ(flagValue(ours, "--split"), "off");
}

TEST(Recipe, FileSettingsComeAfterTheirStepsSwitch)
{
    const Recipe r = parseRecipe(R"({"recipe":"mine","steps":[{"step":"stage1","shape":"polar"},{"step":"curveShift","share":0.5},
        {"step":"stage2","iterations":"auto"},{"step":"keep","mode":"regions","validationStop":5}]})", "r.json");
    EXPECT_EQ(r.name, "mine");
    const Flags flags = recipeFlags(r);
    EXPECT_EQ(flagValue(flags, "--validation-stop"), "5");
    EXPECT_EQ(flagValue(flags, "--curve-shift"), "0.5");
    EXPECT_EQ(flagValue(flags, "--keep"), "regions");
    EXPECT_EQ(flagValue(flags, "--iterations"), "auto");
    EXPECT_EQ(flagValue(flags, "--curve-split"), "off");
    EXPECT_EQ(recipeJson(r)["steps"][1]["share"], "0.5");
}

TEST(Recipe, BadRecipesNameTheFileTheStepAndTheKey)
{
    for (const auto& [text, message] : std::vector<std::pair<std::string, std::string>>{
             {"[]", "needs \"steps\""},
             {R"({"steps":[{"step":"stage1"},{"step":"warp"},{"step":"stage2"}]})", "step 1: unknown step \"warp\""},
             {R"({"steps":[{"step":"stage1","colour":"red"},{"step":"stage2"}]})", "(stage1): unknown setting \"colour\""},
             {R"({"steps":[{"step":"stage2"},{"step":"stage1"}]})", "out of order or repeated"},
             {R"({"steps":[{"step":"stage1"},{"step":"stage2"},{"step":"stage2"}]})", "out of order or repeated"},
             {R"({"steps":[{"step":"stage1"}]})", "needs the step \"stage2\""},
             {R"({"steps":[{"step":"stage1","shape":[1]},{"step":"stage2"}]})", "must be a string or a number"}}) {
        const std::string m = inputErrorMessage([&] { parseRecipe(text, "r.json"); });
        EXPECT_EQ(m.rfind("r.json", 0), 0u) << m;
        EXPECT_NE(m.find(message), std::string::npos) << text << "\n" << m;
    }
    EXPECT_THROW(builtinRecipe("fast"), UsageError);
}

TEST(Recipe, DeformWithARecipeGivesTheBytesOfItsFlags)
{
    TempDir dir;
    DemoModelOptions so;
    so.count = 1500;
    writePly(dir.file("m.ply"), makeDemoModel("stripes", so));
    const std::string base = "-q deform " + dir.file("m.ply") + " --spec " + SPLATWARP_SOURCE_DIR +
                             "/samples/specs/bend.json --nodes 48 --cells 12 --iterations 4 --eval-points 3000 -o ";
    auto run = [&](const std::string& name, const std::string& flags) {
        EXPECT_EQ(runCli(base + dir.file(name) + " " + flags, dir.file(name + ".log")), 0) << fileBytes(dir.file(name + ".log"));
        return fileBytes(dir.file(name + "/deformed.ply"));
    };
    const std::string paper = run("paper", "--recipe paper");
    EXPECT_TRUE(paper == run("flags", "--stage1-shape polar --curve-split off --validated-split off --keep fit --curve-shift 0 --boundary-weight 99"));
    // (--iterations 4 above wins over the paper's 100, as any flag given beside a recipe.)
    EXPECT_FALSE(paper == run("default", ""));
    EXPECT_TRUE(run("default", "") == run("named", "--recipe default"));
    // A flag beside the recipe wins over it.
    EXPECT_TRUE(run("override", "--recipe paper --boundary-weight 1") ==
                run("flags1", "--stage1-shape polar --curve-split off --validated-split off --keep fit --curve-shift 0"));
    std::ofstream(dir.file("r.json")) << R"({"recipe":"bad","steps":[{"step":"stage1","shape":"round"},{"step":"stage2"}]})";
    EXPECT_EQ(runCli(base + dir.file("bad") + " --recipe " + dir.file("r.json"), dir.file("bad.log")), 1);
    EXPECT_NE(fileBytes(dir.file("bad.log")).find("recipe bad: --stage1-shape round"), std::string::npos) << fileBytes(dir.file("bad.log"));
}
