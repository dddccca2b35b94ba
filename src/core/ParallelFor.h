#pragma once
/// @file ParallelFor.h
/// @brief The one parallel-for of the library: oneTBB over [0, n) in chunks of at least `grain`,
///        or a plain serial loop when threaded is false (deterministic debugging, tests comparing
///        serial and parallel results). The body sees either one index or one range.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstddef>

namespace splatwarp {

/// @brief op(begin, end) over consecutive chunks of [0, n).
template <typename RangeOp>
void parallelForRange(std::size_t n, std::size_t grain, bool threaded, const RangeOp& op)
{
    if (n == 0) return;
    if (!threaded) {
        op(std::size_t(0), n);
        return;
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain),
                      [&](const tbb::blocked_range<std::size_t>& r) { op(r.begin(), r.end()); });
}

/// @brief op(i) for every i in [0, n).
template <typename Op>
void parallelFor(std::size_t n, std::size_t grain, bool threaded, const Op& op)
{
    parallelForRange(n, grain, threaded, [&](std::size_t begin, std::size_t end) {
        for (std::size_t i = begin; i != end; ++i) op(i);
    });
}

} // namespace splatwarp
