// Edges of the command line found by a hostile pass (issue 28's smaller cases): where the output
// goes, what an out-of-memory message names, degenerate cameras, and notes that do not flood.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "io/GaussianIO.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;

TEST(CliEdges, WhatCannotReachStandardOutputIsAnError)
{
    TempDir dir;
    ASSERT_EQ(runCli("-q sample stripes --count 100 -o " + dir.file("s.ply")), 0);
    if (!std::filesystem::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
    const int rc = std::system((std::string(SPLATWARP_CLI) + " info " + dir.file("s.ply") + " --json >/dev/full 2>" + dir.file("e.log")).c_str());
    EXPECT_EQ(WEXITSTATUS(rc), 1);
    EXPECT_NE(fileBytes(dir.file("e.log")).find("standard output: write failed"), std::string::npos) << fileBytes(dir.file("e.log"));
}

namespace {

/// Run `command` (CLI arguments) under a 2 GB address-space limit; returns its exit code and output.
std::pair<int, std::string> runUnderTwoGigabytes(const TempDir& dir, const std::string& command)
{
    const std::string cmd = "ulimit -v 2000000; " + std::string(SPLATWARP_CLI) + " -q --threads 1 " + command;
    const int rc = std::system(("bash -c '" + cmd + "' >" + dir.file("e.log") + " 2>&1").c_str());
    return {WEXITSTATUS(rc), fileBytes(dir.file("e.log"))};
}

/// The out-of-memory hint names exactly the memory flags the command has (its --help lists them).
void expectHintNamesItsOwnFlags(const TempDir& dir, const std::string& command, const std::string& log)
{
    ASSERT_NE(log.find("out of memory (lower or check "), std::string::npos) << log;
    ASSERT_EQ(runCli(command + " --help", dir.file("help.txt")), 0);
    const std::string help = fileBytes(dir.file("help.txt"));
    const std::string hint = log.substr(log.find("out of memory"));
    for (const char* flag : {"--points", "--size", "--max-memory", "--samples-per-cell", "--cells"}) {
        bool has = false; // an option line of the help starts with the flag
        std::istringstream lines(help);
        for (std::string line; std::getline(lines, line);) {
            line.erase(0, line.find_first_not_of(' '));
            has = has || line.rfind(std::string(flag) + " ", 0) == 0 || line.rfind(std::string(flag) + ",", 0) == 0;
        }
        const bool named = hint.find(std::string(flag) + ",") != std::string::npos || hint.find(std::string(flag) + ")") != std::string::npos;
        EXPECT_EQ(named, has) << command << " " << flag << "\n" << hint;
    }
}

} // namespace

TEST(CliEdges, OutOfMemoryNamesTheFlagsOfTheCommandThatRan)
{
#ifdef __SANITIZE_ADDRESS__
    GTEST_SKIP() << "ASan reserves terabytes of address space: a 2 GB ulimit -v stops it before main";
#endif
    TempDir dir;
    ASSERT_EQ(runCli("-q sample stripes --count 100 -o " + dir.file("s.ply")), 0);
    // 4e9 held-out points: std::bad_alloc (past a --max-memory that lets them through its estimate).
    // eval has all five memory flags.
    const auto [evalRc, evalLog] = runUnderTwoGigabytes(dir, "eval --rest " + dir.file("s.ply") + " --deformed " + dir.file("s.ply") +
                                                            " --spec " + SPLATWARP_SOURCE_DIR +
                                                            "/samples/specs/rigid.json --points 4000000000 --max-memory 4T");
    EXPECT_EQ(evalRc, 1) << evalLog;
    expectHintNamesItsOwnFlags(dir, "eval", evalLog);
    EXPECT_NE(evalLog.find("--points"), std::string::npos) << evalLog;
    // A 16000 x 16000 picture (4 GB of pixels): render has --size and none of the others.
    const auto [renderRc, renderLog] = runUnderTwoGigabytes(dir, "render " + dir.file("s.ply") + " -o " + dir.file("r.png") + " --size 16000x16000");
    EXPECT_EQ(renderRc, 1) << renderLog;
    expectHintNamesItsOwnFlags(dir, "render", renderLog);
    EXPECT_EQ(renderLog.find("--cells"), std::string::npos) << renderLog;
    EXPECT_FALSE(std::filesystem::exists(dir.file("r.png")));
    // A count the user set is named first (sample has no memory flag of its own).
    const auto [sampleRc, sampleLog] = runUnderTwoGigabytes(dir, "sample stripes --count 400000000 -o " + dir.file("big.ply"));
    EXPECT_EQ(sampleRc, 1) << sampleLog;
    EXPECT_NE(sampleLog.find("out of memory (lower or check --count)"), std::string::npos) << sampleLog;
}

TEST(CliEdges, AZeroCameraAngleIsRefused)
{
    TempDir dir;
    ASSERT_EQ(runCli("-q sample stripes --count 100 -o " + dir.file("s.ply")), 0);
    std::ofstream(dir.file("t.json")) << R"({"camera_angle_x": 0, "w": 32, "h": 32, "frames": [{"file_path": "a",
        "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,5],[0,0,0,1]]}]})";
    EXPECT_EQ(runCli("render " + dir.file("s.ply") + " --camera " + dir.file("t.json") + " -o " + dir.file("a.png"), dir.file("e.log")), 1);
    EXPECT_NE(fileBytes(dir.file("e.log")).find("frame 0: 'camera_angle_x' must be in (0, pi) radians, got 0"), std::string::npos) << fileBytes(dir.file("e.log"));
    EXPECT_FALSE(std::filesystem::exists(dir.file("a.png")));
}

TEST(CliEdges, ManySkippedPlyElementsAreSummarised)
{
    TempDir dir;
    std::ostringstream ply;
    ply << "ply\nformat ascii 1.0\nelement vertex 1\n";
    for (const char* p : {"x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
        ply << "property float " << p << "\n";
    for (int e = 0; e < 2000; ++e) ply << "element extra" << e << " 0\nproperty float v\n";
    ply << "end_header\n0 0 0 0 0 0 0 -1 -1 -1 1 0 0 0\n";
    std::ofstream(dir.file("m.ply")) << ply.str();
    ReadReport report;
    const GaussianCloud g = readGaussians(dir.file("m.ply"), {}, &report);
    EXPECT_EQ(g.size(), 1u);
    ASSERT_EQ(report.notes.size(), 6u);
    EXPECT_EQ(report.notes.back(), "skipped 1995 more elements (0 records)");
}

// deform's --help lists the flags a user touches; --help-all every one (all of them still work).
TEST(CliEdges, DeformHelpListsAtMostTenFlagsAndHelpAllEveryOne)
{
    TempDir dir;
    auto flags = [&](const std::string& args) {
        EXPECT_EQ(runCli(args, dir.file("help.txt")), 0) << args;
        std::istringstream lines(fileBytes(dir.file("help.txt")));
        int n = 0;
        for (std::string line; std::getline(lines, line);) // -h,--help and --help-all are not settings
            n += line.rfind("  -", 0) == 0 && line.rfind("  -h,--help ", 0) != 0 && line.rfind("  --help-all ", 0) != 0;
        return n;
    };
    for (const char* cmd : {"deform", "animate"}) {
        EXPECT_LE(flags(std::string(cmd) + " --help"), 10) << cmd;
        EXPECT_EQ(fileBytes(dir.file("help.txt")).find("--curve-split-max"), std::string::npos) << cmd;
        EXPECT_GE(flags(std::string(cmd) + " --help-all"), 40) << cmd;
        EXPECT_NE(fileBytes(dir.file("help.txt")).find("--curve-split-max"), std::string::npos) << cmd;
    }
}

// Every command that reads a model names every format it reads (one list, tools/ReadArgs.h).
TEST(CliEdges, CommandsThatReadAModelNameEveryFormat)
{
    TempDir dir;
    for (const char* cmd : {"info", "convert", "render", "to-vdb", "deform", "animate"}) {
        ASSERT_EQ(runCli(std::string(cmd) + " --help", dir.file("help.txt")), 0) << cmd;
        const std::string help = fileBytes(dir.file("help.txt"));
        for (const char* format : {".ply", "compressed", ".splat", ".spz", ".sog", "meta.json", ".glb", ".vdb points"})
            EXPECT_NE(help.find(format), std::string::npos) << cmd << " --help does not name " << format;
    }
}

TEST(CliEdges, ADeviceIsNoModelAndACountIsPositive)
{
    TempDir dir;
    if (std::filesystem::exists("/dev/zero")) { // would be read until memory ran out
        EXPECT_EQ(runCli("info /dev/zero", dir.file("z.log")), 1);
        EXPECT_NE(fileBytes(dir.file("z.log")).find("/dev/zero: is not a regular file"), std::string::npos) << fileBytes(dir.file("z.log"));
    }
    EXPECT_EQ(runCli("sample stripes --count -1 -o " + dir.file("q.ply"), dir.file("c.log")), 2);
    EXPECT_EQ(runCli("sample stripes --count 0 -o " + dir.file("q.ply"), dir.file("c.log")), 2);
    EXPECT_FALSE(std::filesystem::exists(dir.file("q.ply")));
}
