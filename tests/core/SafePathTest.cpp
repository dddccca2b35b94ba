/// pathInside(): a path named by a job list or a manifest resolves inside the output folder, whole
/// (every part, existing or not), or is refused naming what named it.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/SafePath.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;
namespace fs = std::filesystem;

TEST(SafePath, MissingPartsAreKeptWhole)
{
    TempDir dir;
    const std::string root = dir.file("out");
    fs::create_directories(root + "/deep");
    EXPECT_EQ(pathInside(root, "sub/s.vdb", "job 0"), root + "/sub/s.vdb");
    EXPECT_EQ(pathInside(root, "deep/er/bend", "job 1"), root + "/deep/er/bend");
    EXPECT_EQ(pathInside(root, "./a/./b", "job 2"), root + "/a/b");
    EXPECT_EQ(pathInside(root, "deep", "job 3"), root + "/deep");
}

TEST(SafePath, ClimbsAbsolutesAndSymlinksAreRefused)
{
    TempDir dir;
    const std::string root = dir.file("out");
    fs::create_directories(root + "/real");
    fs::create_directories(dir.file("outside"));
    fs::create_directory_symlink(dir.file("outside"), root + "/link");
    const auto refused = [&](const std::string& rel, const std::string& part) {
        const std::string m = inputErrorMessage([&] { pathInside(root, rel, "jobs.json: job 4"); });
        EXPECT_NE(m.find("jobs.json: job 4"), std::string::npos) << m;
        EXPECT_NE(m.find(part), std::string::npos) << rel << ": " << m;
    };
    refused("a/../b", "climbs out");         // a ".." after a missing part is still a climb
    refused("missing/../../x", "climbs out");
    refused("real/../../x", "climbs out");
    refused("/etc/x", "absolute");
    refused("link/x.vdb", "symbolic link");
    refused(".", "output folder itself");
    refused("", "empty");
}
