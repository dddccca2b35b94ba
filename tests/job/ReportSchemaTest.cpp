// Every key the reports write is documented in docs/report-schema.md and has one style (camelCase):
// deform's report.json (with every optional block: a full run with --render --vdb --eval-every,
// a rigid run, a Stage I run), eval --json, from-vdb's report and info --json.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "support/TestSupport.h"

using namespace splatwarp::test;

namespace {

/// Key paths by schema section: "a.b", "a.list[].c"; keys that are data (numbers, such as the curve
/// shift's shares) become "*". The field-error blocks every stage, eval and from-vdb share are
/// listed once, in the section "FieldError", relative to the block.
using Paths = std::map<std::string, std::set<std::string>>;

bool isFieldError(const std::string& path)
{
    for (const char* end : {".fieldError", ".latticeError", "stage2.evalCurve[]", "heldOut.noFit", "heldOut.fit"}) {
        const std::string e = end;
        if (path == e.substr(e[0] == '.' ? 1 : 0) || (path.size() > e.size() && path.compare(path.size() - e.size(), e.size(), e) == 0))
            return true;
    }
    return false;
}

void keyPaths(const nlohmann::json& j, const std::string& at, const std::string& section, Paths& out)
{
    if (isFieldError(at)) return keyPaths(j, "", "FieldError", out);
    if (j.is_array()) {
        for (const nlohmann::json& e : j) keyPaths(e, at + "[]", section, out);
    } else if (j.is_object()) {
        for (const auto& [key, value] : j.items()) {
            const bool data = std::regex_match(key, std::regex("[0-9.e+-]+"));
            const std::string path = (at.empty() ? "" : at + ".") + (data ? "*" : key);
            out[section].insert(path);
            keyPaths(value, path, section, out);
        }
    }
}

/// The paths the schema lists in its section `section` ("## deform report.json" ...): the
/// first column of its tables, in backticks.
std::set<std::string> schemaPaths(const std::string& section)
{
    std::ifstream in(std::string(SPLATWARP_SOURCE_DIR) + "/docs/report-schema.md");
    std::set<std::string> paths;
    bool inside = false;
    for (std::string line; std::getline(in, line);) {
        if (line.rfind("## ", 0) == 0) inside = line == "## " + section;
        std::smatch m;
        if (inside && std::regex_search(line, m, std::regex("^\\| `([^`]+)`"))) paths.insert(m[1]);
    }
    return paths;
}

nlohmann::json parseFile(const std::string& path)
{
    std::ifstream in(path);
    return nlohmann::json::parse(in);
}

/// stdout of a CLI call holding one JSON document (after any text before its first brace).
nlohmann::json cliJson(const TempDir& dir, const std::string& args)
{
    EXPECT_EQ(runCli(args + " 2>/dev/null", dir.file("out.json")), 0) << args;
    const std::string text = fileBytes(dir.file("out.json"));
    return nlohmann::json::parse(text.substr(std::min(text.find('{'), text.size())));
}

void expectDocumentedAndCamelCase(const Paths& paths)
{
    for (const auto& [section, found] : paths) {
    const std::set<std::string> schema = schemaPaths(section);
    ASSERT_FALSE(schema.empty()) << "docs/report-schema.md has no section '" << section << "'";
    for (const std::string& path : found) {
        EXPECT_TRUE(schema.count(path)) << section << ": `" << path << "` is written but not in docs/report-schema.md";
        std::istringstream parts(path);
        for (std::string key; std::getline(parts, key, '.');) {
            key = key.substr(0, key.find('['));
            EXPECT_TRUE(key == "*" || std::regex_match(key, std::regex("[a-z][a-zA-Z0-9]*"))) << path << ": key '" << key << "'";
        }
    }
    }
}

} // namespace

TEST(ReportSchema, DeformReportKeysAreDocumentedAndCamelCase)
{
    TempDir dir;
    const std::string model = dir.file("s.ply"), specs = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/";
    ASSERT_EQ(runCli("-q sample stripes --count 1500 -o " + model), 0);
    Paths found;
    ASSERT_EQ(runCli("-q deform " + model + " --spec " + specs + "bend.json -o " + dir.file("bend") +
                     " --iterations 6 --eval-every 3 --render --vdb --recipe default" + kQuickDeform), 0);
    keyPaths(parseFile(dir.file("bend/report.json")), "", "deform report.json", found);
    ASSERT_EQ(runCli("-q deform " + model + " --spec " + specs + "rigid.json -o " + dir.file("rigid") + kQuickDeform), 0);
    keyPaths(parseFile(dir.file("rigid/report.json")), "", "deform report.json", found);
    ASSERT_EQ(runCli("-q deform " + model + " --spec " + specs + "twist.json -o " + dir.file("s1") + " --stage1-only"), 0);
    keyPaths(parseFile(dir.file("s1/report.json")), "", "deform report.json", found);
    // Every block a full run writes is there (so the test sees them): the steps and the extras.
    for (const char* path : {"curveSplit.fans", "validatedSplit.budget", "curveShift.validation.*", "stage2.keep.kept",
                             "stage2.evalCurve", "stage2.fieldError", "stretched.radius", "outputs.field",
                             "recipe.steps[].step", "stage2.skipped"})
        EXPECT_TRUE(found["deform report.json"].count(path)) << path;
    for (const char* path : {"opacity", "inside.points", "imagePsnr.db", "filterVariance", "iteration"})
        EXPECT_TRUE(found["FieldError"].count(path)) << path;
    expectDocumentedAndCamelCase(found);
}

TEST(ReportSchema, EvalFromVdbAndInfoKeysAreDocumentedAndCamelCase)
{
    TempDir dir;
    const std::string model = dir.file("s.ply"), specs = std::string(SPLATWARP_SOURCE_DIR) + "/samples/specs/";
    ASSERT_EQ(runCli("-q sample stripes --count 800 -o " + model), 0);
    Paths found;
    keyPaths(cliJson(dir, "-q eval --rest " + model + " --deformed " + model + " --spec " + specs + "rigid.json --json"), "",
             "FieldError", found);
    ASSERT_EQ(runCli("-q to-vdb " + model + " -o " + dir.file("s.vdb") + " --cells 24"), 0);
    ASSERT_EQ(runCli("-q from-vdb " + dir.file("s.vdb") + " -o " + dir.file("back.ply") + " --iterations 3"), 0);
    keyPaths(parseFile(dir.file("back.report.json")), "", "from-vdb report", found);
    EXPECT_TRUE(found["from-vdb report"].count("fit.rounds[].bestIteration"));
    keyPaths(cliJson(dir, "info " + model + " --json"), "", "info --json", found);
    EXPECT_TRUE(found["info --json"].count("quatNorm.max"));
    expectDocumentedAndCamelCase(found);
}
