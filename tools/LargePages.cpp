/// @file LargePages.cpp
/// @brief The executable's `operator new`: blocks of 4 MiB and more come from allocateLarge()
///        (core/Memory.h: 2 MiB pages where the kernel allows), every other block from malloc, as
///        the default one does; the default `operator delete` (free) releases both. Most of the
///        sample grid's time was first touches of fresh 4 KiB pages of its std::vector arrays (each
///        a fault of microseconds on a virtualised machine); on 2 MiB pages there are 512 times
///        fewer (docs/benchmarks.md, "Outside Stage II"). Only this executable: the Python module and the test binaries
///        keep the default; sanitizer builds too (their allocator must see new and delete pair).
#include <malloc.h>

#include <cstdlib>
#include <new>

#include "core/Memory.h"

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define SPLATWARP_DEFAULT_NEW 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define SPLATWARP_DEFAULT_NEW 1
#endif
#endif

#ifndef SPLATWARP_DEFAULT_NEW
void* operator new(std::size_t bytes) { return splatwarp::allocateLarge(bytes); }

namespace {

/// A fixed mmap threshold at the large blocks' size: each is mapped on its own and unmapped when
/// freed. glibc's default threshold rises to the size of each mapped block freed (up to 32 MiB),
/// after which such blocks come from the heap and stay resident once freed: on 2 MiB pages that
/// raised guitar's peak RSS by 10%.
[[maybe_unused]] const bool kMappedLargeBlocks = mallopt(M_MMAP_THRESHOLD, 4 << 20) == 1;

} // namespace
#endif
