#include "vdb/VdbLibrary.h"

#include <mutex>
#include <nanovdb/NanoVDB.h>
#include <openvdb/openvdb.h>

namespace splatwarp::vdb {

void initialize()
{
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

std::string libraryVersions()
{
    return std::string("OpenVDB ") + openvdb::getLibraryAbiVersionString() + ", NanoVDB " +
           std::to_string(NANOVDB_MAJOR_VERSION_NUMBER) + "." + std::to_string(NANOVDB_MINOR_VERSION_NUMBER) + "." +
           std::to_string(NANOVDB_PATCH_VERSION_NUMBER);
}

} // namespace splatwarp::vdb
