#pragma once
/// @file Hash.h
/// @brief splitmix64's finalizer: spreads every input bit over the 64 output bits. The SOG
///        palette's seeded generator and the .vdb header's content tag both end in it.
#include <cstdint>

namespace splatwarp {

inline std::uint64_t mix64(std::uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

} // namespace splatwarp
