#include "core/MortonOrder.h"

#include <algorithm>
#include <numeric>

#include <tbb/parallel_sort.h>

#include "core/Error.h"
#include "core/ParallelFor.h"

namespace splatwarp {

namespace {

/// 10 bits per axis interleaved: the point's cell of a 1024^3 lattice over [lo, hi].
std::uint64_t mortonKey(const float* p, const float* lo, const float* scale)
{
    std::uint64_t key = 0;
    std::uint32_t c[3];
    for (int a = 0; a < 3; ++a) c[a] = std::uint32_t(std::clamp((double(p[a]) - lo[a]) * scale[a], 0.0, 1023.0));
    for (int bit = 9; bit >= 0; --bit)
        for (int a = 0; a < 3; ++a) key = (key << 1) | ((c[a] >> bit) & 1u);
    return key;
}

} // namespace

MortonOrder::MortonOrder(const float* x, std::size_t m, bool threaded)
{
    if (m > 0xffffffffull) throw InputError(msg("Morton order of ", m, " points; at most 2^32 - 1"));
    if (m == 0) return;
    float lo[3], hi[3], scale[3];
    for (int a = 0; a < 3; ++a) lo[a] = hi[a] = x[a];
    for (std::size_t j = 0; j < m; ++j)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], x[3 * j + a]);
            hi[a] = std::max(hi[a], x[3 * j + a]);
        }
    for (int a = 0; a < 3; ++a) scale[a] = hi[a] > lo[a] ? float(1023.999 / (double(hi[a]) - lo[a])) : 0.0f;
    key.resize(m);
    parallelFor(m, 4096, threaded, [&](std::size_t j) { key[j] = mortonKey(x + 3 * j, lo, scale); });
    order.resize(m);
    std::iota(order.begin(), order.end(), 0u);
    const auto before = [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b] || (key[a] == key[b] && a < b); };
    if (threaded)
        tbb::parallel_sort(order.begin(), order.end(), before);
    else
        std::sort(order.begin(), order.end(), before);
}

} // namespace splatwarp
