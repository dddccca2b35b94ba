#pragma once
/// @file Memory.h
/// @brief Memory budgets: physical memory, "8G"-style sizes, and turning an allocation failure
///        into an error that names the stage.
#include <cstddef>
#include <new>
#include <string>

#include "core/Error.h"

namespace splatwarp {

/// @brief Installed physical memory in bytes (0 when unknown).
std::size_t physicalMemoryBytes();

/// @brief The default budget of a job: 3/4 of physical memory (0 = no limit when unknown).
std::size_t defaultMemoryBudget();

/// @brief "8G", "512M", "1.5T", "64K" or plain bytes -> bytes (binary units).
/// @throws UsageError for anything else (named as `flag` in the message).
std::size_t parseByteSize(const std::string& text, const std::string& flag);

/// @brief "1.5 GiB"-style text.
std::string formatBytes(double bytes);

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
