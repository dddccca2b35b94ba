#pragma once
/// @file TestSupport.h
/// @brief Shared test helpers: data paths (skip when ../shared/data is missing), temp dirs,
///        running the CLI.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <unistd.h>

#include "core/Camera.h"
#include "core/Error.h"

namespace splatwarp::test {

/// @brief Path of a file under ../shared/data, or "" when the data folder is missing.
inline std::string dataPath(const std::string& rel)
{
    const std::filesystem::path p = std::filesystem::path(SPLATWARP_DATA_DIR) / rel;
    return std::filesystem::exists(p) ? p.string() : std::string();
}

/// @brief The bytes of a file ("" when it cannot be read).
inline std::string fileBytes(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// Skip the current test with a message when a shared data file is missing.
#define SPLATWARP_REQUIRE_DATA(var, rel)                                                                 \
    const std::string var = ::splatwarp::test::dataPath(rel);                                         \
    if (var.empty()) GTEST_SKIP() << "../shared/data/" << (rel) << " not present; skipping"

/// @brief A fresh empty directory per test, removed at the end. The pid keeps worktrees that run
///        the same test at the same time apart (std::rand() is unseeded: the same in every process).
class TempDir {
public:
    TempDir()
    {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        mPath = std::filesystem::temp_directory_path() /
                (std::string("splatwarp-") + (info ? info->test_suite_name() : "t") + "-" +
                 (info ? info->name() : "x") + "-" + std::to_string(::getpid()) + "-" + std::to_string(std::rand()));
        std::filesystem::remove_all(mPath);
        std::filesystem::create_directories(mPath);
    }
    ~TempDir() { std::filesystem::remove_all(mPath); }
    std::string file(const std::string& name) const { return (mPath / name).string(); }
    const std::filesystem::path& path() const { return mPath; }

private:
    std::filesystem::path mPath;
};

/// @brief Flags that make a CLI deform of a small model cheap (a coarse lattice, 4^3 samples a cell,
///        a fifth of the judge's points) for tests whose assertions are about what the pipeline
///        does, not how close it fits: about 4x faster, which the sanitizer run multiplies.
inline const std::string kQuickDeform = " --cells 24 --samples-per-cell 4 --eval-points 20000 ";

/// @brief Run the splatwarp CLI with arguments (shell syntax); returns the exit code. Output
///        goes to the given file when set.
inline int runCli(const std::string& args, const std::string& outputFile = "")
{
    std::string cmd = std::string(SPLATWARP_CLI) + " " + args;
    cmd += outputFile.empty() ? " >/dev/null 2>&1" : " >" + outputFile + " 2>&1";
    const int rc = std::system(cmd.c_str());
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

/// @brief The message of the InputError that f() throws, or "" when it throws none.
template <typename F>
std::string inputErrorMessage(const F& f)
{
    try {
        f();
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

/// @brief Pixel position (u, v) and depth of a world point seen by a pinhole camera.
inline Vec3d project(const Camera& c, const Vec3d& p)
{
    const Vec3d t = c.rotation * p + c.translation;
    return {c.fx * t.x / t.z + c.cx, c.fy * t.y / t.z + c.cy, t.z};
}

} // namespace splatwarp::test
