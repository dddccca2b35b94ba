// The deform settings table (job/DeformSettings.h): each row's default text reads back to the
// same record, a bad value is a usage error naming its flag, every flag a recipe sets is a row,
// and the record keeps the keys and values animate's settings hash was made of before the table.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "core/Error.h"
#include "job/DeformSettings.h"
#include "job/Recipe.h"
#include "job/Sequence.h"

using namespace splatwarp;

TEST(DeformSettings, EachDefaultTextReadsBackToTheSameRecord)
{
    const DeformJobOptions defaults = deformDefaults();
    const nlohmann::json record = settingsJson(defaults);
    int read = 0;
    for (const Setting& s : deformSettings()) {
        if (!s.takesValue() || s.text(defaults).empty()) continue;
        DeformJobOptions o = defaults;
        s.set(o, s.text(defaults));
        EXPECT_EQ(settingsJson(o), record) << s.flag << " " << s.text(defaults);
        ++read;
    }
    EXPECT_GE(read, 25);
}

TEST(DeformSettings, FlagsAreUniqueAndABadValueNamesItsFlag)
{
    std::set<std::string> flags;
    for (const Setting& s : deformSettings()) {
        EXPECT_TRUE(flags.insert(s.flag).second) << s.flag;
        EXPECT_FALSE(s.help.empty()) << s.flag;
        if (!s.takesValue()) continue;
        DeformJobOptions o = deformDefaults();
        try {
            s.set(o, "not-a-value");
            ADD_FAILURE() << s.flag << " took 'not-a-value'";
        } catch (const UsageError& e) {
            EXPECT_EQ(std::string(e.what()).rfind(s.flag, 0), 0u) << e.what();
        }
    }
}

// A number past what its field holds is refused, not wrapped (--cells 1e10 would wrap an int) or
// made infinite (a float's 1e300).
TEST(DeformSettings, ANumberPastItsFieldIsRefused)
{
    for (const char* flag : {"--cells", "--nodes", "--eval-every", "--coverage-steps", "--validation-draws"}) {
        DeformJobOptions o = deformDefaults();
        EXPECT_THROW(deformSetting(flag).set(o, "1e10"), UsageError) << flag;
        EXPECT_THROW(deformSetting(flag).set(o, "2147483648"), UsageError) << flag;
        EXPECT_NO_THROW(deformSetting(flag).set(o, "7")) << flag;
    }
    DeformJobOptions o = deformDefaults(); // a float flag: not made infinite
    EXPECT_THROW(deformSetting("--boundary-weight").set(o, "1e300"), UsageError);
    EXPECT_NO_THROW(deformSetting("--boundary-weight").set(o, "1e30"));
}

TEST(DeformSettings, EverySwitchChangesTheRecordAndEveryFlagARecipeSetsIsARow)
{
    const DeformJobOptions defaults = deformDefaults();
    for (const Setting& s : deformSettings()) {
        if (s.takesValue()) continue;
        DeformJobOptions o = defaults;
        s.set(o, "true");
        EXPECT_NE(settingsJson(o), settingsJson(defaults)) << s.flag;
    }
    for (const char* name : {"paper", "default"})
        for (const auto& [flag, value] : recipeFlags(builtinRecipe(name))) {
            DeformJobOptions o = defaults;
            EXPECT_NO_THROW(deformSetting(flag).set(o, value)) << name << " " << flag << " " << value;
        }
}

// The record's keys and values are those animate hashed before the table existed: the hash of a
// default run (and of one with every step-changing word off its default) is the one older
// manifests hold, so their frames are resumed, not made again.
TEST(DeformSettings, TheRecordKeepsTheHashOfEarlierRuns)
{
    DeformJobOptions o = deformDefaults();
    // 41 since the 1.5x budget: maxGaussians and budgetMerge written always, as the budget changed
    // the default's output (a resume must not take an earlier default run's frames for this one's);
    // 42 since validationDraws, for the same reason (auto doubles small models' validation points).
    EXPECT_EQ(settingsJson(o).size(), 42u);
    const nlohmann::json before = settingsJson(o);
    EXPECT_EQ(before["maxGaussians"], "1.5x");
    EXPECT_EQ(before["budgetMerge"], true);
    for (const auto& [flag, value] : std::initializer_list<std::pair<const char*, const char*>>{
             {"--keep", "regions"}, {"--validated-split", "off"}, {"--max-gaussians", "2x"}, {"--curve-split-prune", "3"}})
        deformSetting(flag).set(o, value);
    const nlohmann::json after = settingsJson(o);
    EXPECT_EQ(after.size(), 45u); // three keys written only off their defaults
    EXPECT_EQ(after["curveSplitPrune"], 3.0);
    EXPECT_EQ(after["keepPerGaussian"], false);
    EXPECT_EQ(after["validatedSplit"], false);
    EXPECT_EQ(after["maxGaussians"], "2x");
    // No budget: the key says so, and the merge is not written (it does nothing).
    DeformJobOptions none = deformDefaults();
    deformSetting("--max-gaussians").set(none, "none");
    EXPECT_FALSE(none.maxGaussians);
    EXPECT_EQ(settingsJson(none)["maxGaussians"], "none");
    EXPECT_FALSE(settingsJson(none).contains("budgetMerge"));
    EXPECT_EQ(before["samplesPerCell"], "auto");
    EXPECT_EQ(before["curveShift"], "auto");
    EXPECT_EQ(before["validationDraws"], "auto");
    DeformJobOptions draws = deformDefaults();
    deformSetting("--validation-draws").set(draws, "20");
    EXPECT_EQ(draws.validationDraws, 20);
    EXPECT_EQ(settingsJson(draws)["validationDraws"], 20);
    EXPECT_THROW(deformSetting("--validation-draws").set(draws, "0"), UsageError);
    EXPECT_EQ(before["nodes"], -1);
}

TEST(DeformSettings, FineCellsAndTheirThresholdMayComeInEitherOrder)
{
    const Setting& cells = deformSetting("--fine-cells");
    const Setting& below = deformSetting("--fine-below");
    DeformJobOptions a = deformDefaults(), b = deformDefaults(), c = deformDefaults();
    cells.set(a, "auto");
    below.set(a, "2");
    below.set(b, "2");
    cells.set(b, "auto");
    below.set(c, "2");
    EXPECT_EQ(a.grid.fineBelow, 2.0f);
    EXPECT_EQ(b.grid.fineBelow, 2.0f);
    EXPECT_EQ(c.grid.fineBelow, 0.0f); // the threshold alone turns nothing on
    EXPECT_EQ(settingsJson(c), settingsJson(deformDefaults()));
}
