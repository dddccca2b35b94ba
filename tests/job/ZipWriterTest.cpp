// The zip of a sequence: read back by an independent reader (Python's zipfile), ZIP64 records
// included, and only regular files of their recorded size go in.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sys/stat.h>

#include "job/ZipWriter.h"
#include "support/TestSupport.h"

using namespace splatwarp;
using namespace splatwarp::test;
namespace fs = std::filesystem;

namespace {

/// Python's zipfile: testzip() (CRCs) and each member's bytes against the file's.
int checkWithPython(const std::string& zip, const std::string& dir)
{
    const std::string script = "import zipfile,sys\nz=zipfile.ZipFile(sys.argv[1])\nassert z.testzip() is None\n"
                               "for n in z.namelist():\n  assert z.read(n)==open(sys.argv[2]+'/'+n,'rb').read(), n\n"
                               "print(len(z.namelist()))\n";
    std::ofstream(dir + "/check.py") << script;
    return std::system(("python3 " + dir + "/check.py " + zip + " " + dir + " >/dev/null").c_str());
}

std::vector<ZipMember> twoFiles(const TempDir& dir)
{
    fs::create_directories(dir.file("frames"));
    std::ofstream(dir.file("frames/a.ply"), std::ios::binary) << std::string(70000, 'a');
    std::ofstream(dir.file("frames/b.ply"), std::ios::binary) << "bee";
    return {{"frames/a.ply", 70000}, {"frames/b.ply", 3}};
}

} // namespace

TEST(ZipWriter, AnIndependentReaderReadsItWithAndWithoutZip64)
{
    if (std::system("python3 -c 'import zipfile' >/dev/null 2>&1") != 0) GTEST_SKIP() << "python3 not present";
    TempDir dir;
    const std::vector<ZipMember> members = twoFiles(dir);
    writeZip(dir.file("plain.zip"), dir.path().string(), members);
    EXPECT_EQ(checkWithPython(dir.file("plain.zip"), dir.path().string()), 0);
    writeZip(dir.file("z64.zip"), dir.path().string(), members, 0); // every size and offset as ZIP64
    EXPECT_EQ(checkWithPython(dir.file("z64.zip"), dir.path().string()), 0);
    EXPECT_GT(fs::file_size(dir.file("z64.zip")), fs::file_size(dir.file("plain.zip")));
    // The same files give the same bytes (no clock in the archive).
    writeZip(dir.file("again.zip"), dir.path().string(), members);
    EXPECT_EQ(fileBytes(dir.file("again.zip")), fileBytes(dir.file("plain.zip")));
}

TEST(ZipWriter, OnlyRegularFilesOfTheirRecordedSizeGoIn)
{
    TempDir dir;
    std::vector<ZipMember> members = twoFiles(dir);
    auto refused = [&](const std::vector<ZipMember>& m, const std::string& message) {
        try {
            writeZip(dir.file("out.zip"), dir.path().string(), m);
            ADD_FAILURE() << "accepted: " << message;
        } catch (const IoError& e) {
            EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
        }
        EXPECT_FALSE(fs::exists(dir.file("out.zip")));
    };
    refused({{"frames/a.ply", 69999}}, "has 70000 bytes where its manifest entry records 69999");
    fs::create_symlink("/dev/zero", dir.file("frames/zero.ply"));
    refused({{"frames/zero.ply", 100}}, "is not a regular file");
    ASSERT_EQ(::mkfifo(dir.file("frames/fifo.ply").c_str(), 0644), 0);
    refused({{"frames/fifo.ply", 100}}, "is not a regular file"); // never opened: no hang
    refused({{"frames/missing.ply", 1}}, "cannot read");
    for (const auto& e : fs::directory_iterator(dir.path())) EXPECT_NE(e.path().extension(), ".tmp") << e.path();
}
