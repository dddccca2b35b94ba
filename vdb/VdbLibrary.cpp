#include "vdb/VdbLibrary.h"

#include <dlfcn.h>
#include <mutex>
#include <nanovdb/NanoVDB.h>
#include <openvdb/openvdb.h>

namespace splatwarp::vdb {

namespace {

/// Debian's OpenVDB logs through log4cplus to stdout, in colour: a warning about a file landed
/// inside `info --json`'s output. Its logger is configured anew, to stderr, plainly (found at run
/// time: the library is loaded with OpenVDB, its headers are not installed; an OpenVDB without
/// log4cplus writes to std::cerr itself).
void logToStderr()
{
    using Configure = int (*)(const char*);
    const auto configure = reinterpret_cast<Configure>(dlsym(RTLD_DEFAULT, "log4cplus_str_configure"));
    if (!configure) return;
    configure("log4cplus.logger.openvdb=WARN, OPENVDB\n"
              "log4cplus.additivity.openvdb=false\n"
              "log4cplus.appender.OPENVDB=log4cplus::ConsoleAppender\n"
              "log4cplus.appender.OPENVDB.logToStdErr=true\n"
              "log4cplus.appender.OPENVDB.layout=log4cplus::PatternLayout\n"
              "log4cplus.appender.OPENVDB.layout.ConversionPattern=splatwarp: OpenVDB %p: %m%n\n");
}

} // namespace

void initialize()
{
    static std::once_flag once;
    std::call_once(once, [] {
        openvdb::initialize();
        logToStderr();
    });
}

std::string libraryVersions()
{
    return std::string("OpenVDB ") + openvdb::getLibraryAbiVersionString() + ", NanoVDB " +
           std::to_string(NANOVDB_MAJOR_VERSION_NUMBER) + "." + std::to_string(NANOVDB_MINOR_VERSION_NUMBER) + "." +
           std::to_string(NANOVDB_PATCH_VERSION_NUMBER);
}

} // namespace splatwarp::vdb
