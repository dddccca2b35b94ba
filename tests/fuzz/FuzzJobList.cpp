/// libFuzzer target: parseJobList() (batch's JOBS.json), then checkJobPaths() of what it accepts
/// against an output folder that does not exist (paths are checked, nothing is written).
#include <cstddef>
#include <cstdint>
#include <string>

#include "job/JobList.h"
#include "core/Error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    try {
        const auto jobs = splatwarp::parseJobList(std::string(reinterpret_cast<const char*>(data), size), "fuzz-input");
        splatwarp::checkJobPaths(jobs, "/nonexistent/fuzz-out", "/nonexistent/jobs.json");
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
