#include "core/Memory.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <sys/mman.h>
#include <unistd.h>

namespace splatwarp {

std::size_t physicalMemoryBytes()
{
    const long pages = ::sysconf(_SC_PHYS_PAGES), pageSize = ::sysconf(_SC_PAGE_SIZE);
    return pages > 0 && pageSize > 0 ? std::size_t(pages) * std::size_t(pageSize) : 0;
}

void* allocateLarge(std::size_t bytes)
{
    constexpr std::size_t kHuge = std::size_t(2) << 20;
    if (bytes < 2 * kHuge) {
        if (void* p = std::malloc(bytes > 0 ? bytes : 1)) return p;
        throw std::bad_alloc();
    }
    const std::size_t rounded = (bytes + kHuge - 1) / kHuge * kHuge;
    void* p = std::aligned_alloc(kHuge, rounded);
    if (!p) throw std::bad_alloc();
#ifdef MADV_HUGEPAGE
    ::madvise(p, rounded, MADV_HUGEPAGE); // advice only: without huge pages it is an ordinary buffer
#endif
    return p;
}

void freeLarge(void* p) noexcept { std::free(p); }

void releaseFreedMemory() noexcept
{
#if defined(__GLIBC__)
    ::malloc_trim(0);
#endif
}

std::size_t defaultMemoryBudget() { return physicalMemoryBytes() / 4 * 3; }

std::size_t residentMemoryBytes()
{
    // statm: size resident shared ... in pages
    std::FILE* f = std::fopen("/proc/self/statm", "r");
    if (!f) return 0;
    unsigned long long size = 0, resident = 0;
    const int read = std::fscanf(f, "%llu %llu", &size, &resident);
    std::fclose(f);
    const long pageSize = ::sysconf(_SC_PAGE_SIZE);
    return read == 2 && pageSize > 0 ? std::size_t(resident) * std::size_t(pageSize) : 0;
}

MemoryRoom memoryRoom(std::size_t budget) { return {double(budget), double(residentMemoryBytes())}; }

std::string MemoryRoom::text() const
{
    return "the " + formatBytes(std::max(0.0, left())) + " that --max-memory " + formatBytes(budget) + " leaves beside the " +
           formatBytes(used) + " this process holds";
}

std::size_t parseByteSize(const std::string& text, const std::string& flag)
{
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    double unit = 1.0;
    const std::string suffix = end ? std::string(end) : std::string();
    if (suffix == "K" || suffix == "k") unit = 1024.0;
    else if (suffix == "M" || suffix == "m") unit = 1024.0 * 1024.0;
    else if (suffix == "G" || suffix == "g") unit = 1024.0 * 1024.0 * 1024.0;
    else if (suffix == "T" || suffix == "t") unit = 1024.0 * 1024.0 * 1024.0 * 1024.0;
    else if (!suffix.empty()) unit = -1.0;
    const double bytes = v * unit;
    if (end == text.c_str() || unit < 0 || !std::isfinite(bytes) || !(bytes > 0) || bytes > 1e18)
        throw UsageError(msg(flag, " must be a positive size such as 8G, 512M or 1073741824, got '", text, "'"));
    return std::size_t(bytes);
}

std::string formatBytes(double bytes)
{
    static const char* const units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
    int u = 0;
    while (bytes >= 1024.0 && u < 6) {
        bytes /= 1024.0;
        ++u;
    }
    char text[64];
    std::snprintf(text, sizeof(text), u == 0 ? "%.0f %s" : "%.3g %s", bytes, units[u]);
    return text;
}

} // namespace splatwarp
