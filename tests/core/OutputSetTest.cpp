/// AtomicFile and OutputSet: refused destinations, all-or-nothing commits, cleanup on failure
/// and on SIGTERM (issue 11 groups 2, 4 and the 249-character name of group 10).
#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;
namespace fs = std::filesystem;

namespace {

std::string slurp(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

std::size_t entries(const fs::path& dir)
{
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++n;
    return n;
}

std::string ioErrorMessage(const std::function<void()>& f)
{
    try {
        f();
    } catch (const IoError& e) {
        return e.what();
    }
    return "";
}

} // namespace

TEST(OutputSet, RefusesDestinationsThatAreNotPlainNewOrRegularFiles)
{
    TempDir dir;
    EXPECT_NE(ioErrorMessage([] { AtomicFile f(""); }).find("empty output path"), std::string::npos);
    EXPECT_NE(ioErrorMessage([&] { AtomicFile f(dir.path().string()); }).find("is a directory"), std::string::npos);
    // /dev/null is a character device: it used to be replaced by a regular file.
    EXPECT_NE(ioErrorMessage([] { AtomicFile f("/dev/null"); }).find("not a regular file"), std::string::npos);
    writeFileAtomic(dir.file("target"), "x");
    fs::create_symlink(dir.file("target"), dir.file("link"));
    EXPECT_NE(ioErrorMessage([&] { writeFileAtomic(dir.file("link"), "y"); }).find("symbolic link"), std::string::npos);
    EXPECT_TRUE(fs::is_symlink(dir.file("link")));
    EXPECT_EQ(slurp(dir.file("target")), "x");
}

TEST(OutputSet, RefusesAnOutputThatIsAnInputUnderAnotherName)
{
    TempDir dir;
    writeFileAtomic(dir.file("model.ply"), "model");
    OutputSet outputs({dir.file("model.ply")});
    const std::string sameFile = (dir.path() / "." / "model.ply").string();
    EXPECT_NE(ioErrorMessage([&] { writeFileAtomic(sameFile, "vdb"); }).find("is also an input"), std::string::npos);
    EXPECT_EQ(slurp(dir.file("model.ply")), "model");
}

TEST(OutputSet, CommitsAllOutputsTogetherOrNone)
{
    TempDir dir;
    const fs::path out = dir.path() / "a" / "b";
    {
        OutputSet outputs;
        outputs.createDirectory(out.string());
        writeFileAtomic((out / "one.txt").string(), "1");
        writeFileAtomic((out / "two.txt").string(), "2");
        EXPECT_FALSE(fs::exists(out / "one.txt")); // staged, not visible yet
        // No commit (a later stage failed): the staged files and the created folders go.
    }
    EXPECT_EQ(entries(dir.path()), 0u);
    {
        OutputSet outputs;
        outputs.createDirectory(out.string());
        writeFileAtomic((out / "stale.txt").string(), "old");
        outputs.commit();
    }
    {
        OutputSet outputs;
        outputs.createDirectory(out.string());
        writeFileAtomic((out / "one.txt").string(), "1");
        outputs.removeOnCommit((out / "stale.txt").string());
        outputs.commit();
    }
    EXPECT_EQ(slurp((out / "one.txt").string()), "1");
    EXPECT_FALSE(fs::exists(out / "stale.txt"));
    EXPECT_EQ(entries(out), 1u);
}

TEST(OutputSet, NameOf249CharactersStillHasATemporary)
{
    TempDir dir;
    const std::string name = std::string(245, 'n') + ".ply";
    writeFileAtomic(dir.file(name), "ok");
    EXPECT_EQ(slurp(dir.file(name)), "ok");
}

TEST(OutputSet, SigtermRemovesStagedFilesAndCreatedFolders)
{
    TempDir dir;
    const fs::path out = dir.path() / "job";
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        installSignalCleanup();
        OutputSet outputs;
        outputs.createDirectory(out.string());
        writeFileAtomic((out / "baseline.ply").string(), "staged");
        AtomicFile partial((out / "deformed.ply").string());
        std::ofstream(partial.tempPath()) << "half written";
        std::raise(SIGTERM);
        _exit(0); // not reached
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM);
    EXPECT_EQ(entries(dir.path()), 0u) << "left: " << (fs::exists(out) ? "job/" : "");
}

// A render of 6,000 views holds 6,000 temporaries at once: a signal removes every one (the
// cleanup had 4,096 fixed slots and silently skipped the rest).
TEST(OutputSet, SigintRemovesMoreTemporariesThanOneChunkOfSlots)
{
    TempDir dir;
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        installSignalCleanup();
        OutputSet outputs;
        for (int i = 0; i < 6000; ++i) writeFileAtomic(dir.file("view_" + std::to_string(i) + ".png"), "v");
        std::raise(SIGINT);
        _exit(0); // not reached
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT);
    EXPECT_EQ(entries(dir.path()), 0u);
}

TEST(OutputSet, RefusesTwoOutputsOnOnePath)
{
    TempDir dir;
    OutputSet outputs;
    outputs.checkTarget(dir.file("a.ply"));
    EXPECT_THROW(outputs.checkTarget(dir.path().string() + "/./a.ply"), IoError);
    writeFileAtomic(dir.file("b.json"), "1");
    EXPECT_THROW(writeFileAtomic(dir.file("b.json"), "2"), IoError); // would replace the first silently
    outputs.commit();
    EXPECT_EQ(slurp(dir.file("b.json")), "1");
}

// A command that fails leaves no folder it created, and one that succeeds keeps them.
TEST(OutputSet, DirectoryGuardRemovesOnlyTheEmptyFoldersItCreated)
{
    TempDir dir;
    fs::create_directories(dir.file("kept"));
    {
        DirectoryGuard dirs;
        dirs.create(dir.file("kept/a/b"));
        dirs.create(dir.file("c"));
        std::ofstream(dir.file("c/user.txt")) << "x";
    }
    EXPECT_TRUE(fs::exists(dir.file("kept")));
    EXPECT_FALSE(fs::exists(dir.file("kept/a")));
    EXPECT_TRUE(fs::exists(dir.file("c/user.txt")));
    {
        DirectoryGuard dirs;
        dirs.create(dir.file("d/e"));
        dirs.keep();
    }
    EXPECT_TRUE(fs::is_directory(dir.file("d/e")));
}

// An output's missing folder is made before the work (a long train or fit ended in "cannot open
// for writing") and is gone again when the command fails; a file where a folder belongs is refused.
TEST(OutputSet, AnOutputsMissingFolderIsMadeBeforeTheWorkAndRemovedOnFailure)
{
    TempDir dir;
    {
        OutputSet outputs;
        outputs.checkTarget(dir.file("new/deep/a.ply"));
        EXPECT_TRUE(fs::is_directory(dir.file("new/deep")));
    } // never committed: the command failed
    EXPECT_FALSE(fs::exists(dir.file("new")));
    {
        OutputSet outputs;
        outputs.checkTarget(dir.file("new/deep/a.ply"));
        writeFileAtomic(dir.file("new/deep/a.ply"), "1");
        outputs.commit();
    }
    EXPECT_EQ(slurp(dir.file("new/deep/a.ply")), "1");
    writeFileAtomic(dir.file("plain"), "x");
    OutputSet outputs;
    EXPECT_NE(ioErrorMessage([&] { outputs.checkTarget(dir.file("plain/a.ply")); }).find("is not a directory"),
              std::string::npos);
    EXPECT_NE(ioErrorMessage([&] { outputs.checkTarget(dir.file("plain/b/a.ply")); }).find("cannot create"),
              std::string::npos);
    EXPECT_EQ(slurp(dir.file("plain")), "x");
}

TEST(OutputSet, PlantedSymlinksAndFifosAtTemporaryNamesArePassedOver)
{
    // The temporaries' names (pid, counter) can be guessed: a symlink or FIFO placed under the
    // next ones must be neither written through nor blocked on.
    TempDir dir;
    writeFileAtomic(dir.file("victim"), "the user's file");
    unsigned next = 0;
    {
        const AtomicFile probe(dir.file("probe")); // its temporary shows where the counter is
        const std::string name = fs::path(probe.tempPath()).filename().string();
        next = unsigned(std::stoul(name.substr(name.find('-') + 1))) + 1;
    }
    std::vector<std::string> planted;
    for (unsigned n = next; n < next + 64; ++n) {
        const std::string path = dir.file(msg(".sw", ::getpid(), "-", n, ".tmp"));
        if (n % 2) fs::create_symlink(dir.file("victim"), path);
        else ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
        planted.push_back(path);
    }
    writeFileAtomic(dir.file("out.json"), "{}\n");
    EXPECT_EQ(slurp(dir.file("out.json")), "{}\n");
    EXPECT_TRUE(fs::is_regular_file(fs::symlink_status(dir.file("out.json"))));
    EXPECT_EQ(slurp(dir.file("victim")), "the user's file");
    for (const std::string& p : planted) EXPECT_FALSE(fs::is_regular_file(fs::symlink_status(p))) << p; // left as planted
    for (const std::string& p : planted) fs::remove(p);
}
