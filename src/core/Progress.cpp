#include "core/Progress.h"

#include <atomic>
#include <cstdio>

namespace splatwarp {

namespace {
std::atomic<bool> gProgress{false};
}

void setProgressEnabled(bool enabled) { gProgress = enabled; }
bool progressEnabled() { return gProgress; }

void progress(const std::string& line)
{
    if (gProgress) std::fprintf(stderr, "splatwarp: %s\n", line.c_str());
}

} // namespace splatwarp
