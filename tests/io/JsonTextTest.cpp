// Deeply nested JSON in any file we read is refused with the file's name, never a crash: 100,000
// levels parse, but printing the value (a spec's "version" in its message) or copying it (a
// manifest entry at --merge) recursed past the stack.
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "core/Error.h"
#include "deform/AnimSpec.h"
#include "deform/DeformSpec.h"
#include "io/CameraFiles.h"
#include "io/JsonText.h"
#include "job/JobList.h"
#include "job/Recipe.h"
#include "job/Sequence.h"

namespace splatwarp {
namespace {

std::string nested(int depth) { return std::string(std::size_t(depth), '[') + std::string(std::size_t(depth), ']'); }

TEST(JsonText, TheNestingLimitIsExact)
{
    EXPECT_NO_THROW(parseJson(nested(kMaxJsonDepth)));
    EXPECT_THROW(parseJson(nested(kMaxJsonDepth + 1)), nlohmann::json::exception);
    EXPECT_THROW(parseJson(nested(100000)), JsonTooDeep);
}

TEST(JsonText, EveryReaderRefusesDeepValuesNamingItsFile)
{
    const std::string deep = nested(100000);
    const std::string handles = R"("handles": [{"box": {"min": [0,0,0], "max": [1,1,1]}, "fixed": true}])";
    const std::vector<std::pair<std::string, std::function<void()>>> readers = {
        {"spec.json", [&] { parseDeformSpec(R"({"version": )" + deep + ", " + handles + "}", "spec.json"); }},
        {"spec.json", [&] { parseDeformSpec(R"({"version": 1, "units": )" + deep + ", " + handles + "}", "spec.json"); }},
        {"anim.json", [&] { parseAnimSpec(R"({"frames": 4, "x": )" + deep + ", " + handles + "}", "anim.json"); }},
        {"jobs.json", [&] { parseJobList(R"({"jobs": )" + deep + "}", "jobs.json"); }},
        {"recipe.json", [&] { parseRecipe(R"({"steps": )" + deep + "}", "recipe.json"); }},
        {"manifest.shard-0.json", [&] { parseManifest(R"({"entries": [)" + deep + "]}", "manifest.shard-0.json"); }},
        {"cameras.json", [&] { parseCameraFile(deep, "cameras.json"); }},
    };
    for (const auto& [name, read] : readers) {
        try {
            read();
            ADD_FAILURE() << name << " was accepted";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("deeper than 256"), std::string::npos) << e.what();
        }
    }
}

} // namespace
} // namespace splatwarp
