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

/// A fixed mmap threshold: blocks of 16 MiB and more are mapped on their own and unmapped when
/// freed; smaller ones are reused from the heap, so the warp's copy of the samples and the solver's
/// arrays do not fault on fresh pages again. glibc's default threshold rises to the size of each
/// mapped block freed (up to 32 MiB): guitar's peak RSS 0.796 -> 1.05-1.32 GB. At 16 MiB it is
/// 0.84 GB (+5%), and the demo's deform 0.5 s faster than at 4 MiB (docs/benchmarks.md).
[[maybe_unused]] const bool kMappedLargeBlocks = mallopt(M_MMAP_THRESHOLD, 16 << 20) == 1;

} // namespace
#endif
