#pragma once
/// @file Memory.h
/// @brief Memory budgets: physical memory, "8G"-style sizes, and turning an allocation failure
///        into an error that names the stage.
#include <cstddef>
#include <new>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/Error.h"

namespace splatwarp {

/// @brief Installed physical memory in bytes (0 when unknown).
std::size_t physicalMemoryBytes();

/// @brief The default budget of a job: 3/4 of physical memory (0 = no limit when unknown).
std::size_t defaultMemoryBudget();

/// @brief Resident memory of this process now, in bytes (0 when unknown: not Linux).
std::size_t residentMemoryBytes();

/// @brief What a --max-memory budget leaves beside what this process holds, read once
///        (memoryRoom()), for estimates made before an allocation.
struct MemoryRoom {
    double budget = 0, used = 0;
    /// Bytes left; negative when the process already holds more than the budget.
    double left() const { return budget - used; }
    /// "the 2 GiB that --max-memory 8 GiB leaves beside the 6 GiB this process holds"
    std::string text() const;
};
MemoryRoom memoryRoom(std::size_t budget);

/// @brief "8G", "512M", "1.5T", "64K" or plain bytes -> bytes (binary units).
/// @throws UsageError for anything else (named as `flag` in the message).
std::size_t parseByteSize(const std::string& text, const std::string& flag);

/// @brief "1.5 GiB"-style text.
std::string formatBytes(double bytes);

/// @brief Memory for a large buffer: at least 4 MiB goes on 2 MiB pages where the kernel allows
///        (transparent huge pages on request). First touches of fresh pages are most of a short
///        Stage II run's set-up and first coverage build on the machines measured (virtualised:
///        each 4 KiB fault costs microseconds); 512 times fewer faults. Throws std::bad_alloc.
void* allocateLarge(std::size_t bytes);
void freeLarge(void* p) noexcept;

/// @brief Hand the heap's free pages back to the system (glibc's malloc_trim; elsewhere nothing).
///        For a loop that frees and allocates many blocks per round on several threads: freed
///        memory stays resident in the threads' arenas and the fragments add up over the rounds.
void releaseFreedMemory() noexcept;

/// @brief Allocator of BigVector: allocateLarge(), and elements default-initialised (no zeroing on
///        resize(n); resize(n, value) and assign() still write their value).
template <typename T>
struct LargeAllocator {
    static_assert(std::is_trivially_copyable_v<T>, "large buffers hold plain data");
    using value_type = T;
    LargeAllocator() = default;
    template <typename U>
    LargeAllocator(const LargeAllocator<U>&) noexcept {}
    T* allocate(std::size_t n) { return static_cast<T*>(allocateLarge(n * sizeof(T))); }
    void deallocate(T* p, std::size_t) noexcept { freeLarge(p); }
    template <typename U>
    void construct(U* p) noexcept { ::new (static_cast<void*>(p)) U; }
    template <typename U, typename... Args>
    void construct(U* p, Args&&... args) { ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...); }
    template <typename U>
    bool operator==(const LargeAllocator<U>&) const noexcept { return true; }
    template <typename U>
    bool operator!=(const LargeAllocator<U>&) const noexcept { return false; }
};

/// @brief A vector for large per-run arrays: huge pages, and resize(n) leaves new elements
///        unwritten (write before reading).
template <typename T>
using BigVector = std::vector<T, LargeAllocator<T>>;

/// @brief resize(n) of a buffer whose contents the caller rewrites: a growth past the capacity
///        frees the old block before allocating, where resize() would hold both while it copies
///        (a Stage II coverage rebuild that adds pairs: old + new partials at once).
template <typename T, typename A>
void resizeDiscarding(std::vector<T, A>& v, std::size_t n)
{
    if (n > v.capacity()) std::vector<T, A>().swap(v);
    v.resize(n);
}

/// @brief Run f(); an allocation failure becomes InputError "<stage>: out of memory ...".
template <typename F>
auto runStage(const char* stage, F&& f) -> decltype(f())
{
    try {
        return f();
    } catch (const std::bad_alloc&) {
        throw InputError(msg(stage, ": out of memory (lower --cells / --samples-per-cell, or raise --max-memory "
                                    "if the machine has more)"));
    }
}

} // namespace splatwarp
