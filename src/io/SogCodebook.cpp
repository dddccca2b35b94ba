/// The scalar codebook of SOG: 256 entries for log scales, f_dc and the SH palette's values.
/// splat-transform quantises scalars with a histogram dynamic programme; ours is plain Lloyd
/// iterations over the sorted values, deterministic without a seed. The SH palette: SogKmeans.cpp.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "io/SogFormat.h"

namespace splatwarp::sog {

namespace {

constexpr int kCodebookSize = 256;
constexpr int kScalarIterations = 64;

// Lloyd on sorted values: each entry owns the values between the midpoints to its neighbours, so
// an iteration is a binary search per boundary and a mean from prefix sums.
void lloydSorted(const std::vector<float>& sorted, std::vector<double>& c)
{
    std::vector<double> prefix(sorted.size() + 1, 0.0);
    for (std::size_t i = 0; i < sorted.size(); ++i) prefix[i + 1] = prefix[i] + sorted[i];
    for (int it = 0; it < kScalarIterations; ++it) {
        std::size_t lo = 0;
        bool moved = false;
        for (std::size_t k = 0; k < c.size(); ++k) {
            const std::size_t hi = k + 1 == c.size() ? sorted.size()
                : std::size_t(std::lower_bound(sorted.begin(), sorted.end(), float(0.5 * (c[k] + c[k + 1]))) - sorted.begin());
            if (hi > lo) {
                const double mean = (prefix[hi] - prefix[lo]) / double(hi - lo);
                moved |= mean != c[k];
                c[k] = mean;
            }
            lo = std::max(lo, hi);
        }
        std::sort(c.begin(), c.end());
        if (!moved) break;
    }
}

std::uint8_t nearestEntry(const std::vector<float>& entries, float v)
{
    const auto it = std::lower_bound(entries.begin(), entries.end(), v);
    std::size_t k = std::size_t(it - entries.begin());
    if (k == entries.size()) return std::uint8_t(k - 1);
    if (k > 0 && v - entries[k - 1] <= entries[k] - v) --k;
    return std::uint8_t(k);
}

} // namespace

Codebook quantize256(const std::vector<float>& values)
{
    Codebook book;
    std::vector<float> sorted(values);
    std::sort(sorted.begin(), sorted.end());
    std::vector<float> distinct(sorted);
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    std::vector<double> c;
    if (distinct.size() <= std::size_t(kCodebookSize)) {
        c.assign(distinct.begin(), distinct.end()); // every value exact
    } else {
        // Half the start at quantiles (the dense middle), half spread over the range: sparse tails
        // (an f_dc far outside the rest) keep entries of their own instead of joining the bulk.
        const double lo = sorted.front(), hi = sorted.back();
        for (int k = 0; k < kCodebookSize / 2; ++k) {
            c.push_back(sorted[std::min(sorted.size() - 1, (2 * std::size_t(k) + 1) * sorted.size() / kCodebookSize)]);
            c.push_back(lo + (hi - lo) * (k + 0.5) / (kCodebookSize / 2));
        }
        std::sort(c.begin(), c.end());
        c.erase(std::unique(c.begin(), c.end()), c.end());
        lloydSorted(sorted, c);
    }
    book.entries.assign(c.begin(), c.end());
    if (book.entries.empty()) book.entries.push_back(0.0f);
    book.entries.resize(kCodebookSize, book.entries.back()); // pad ascending with the last, as splat-transform
    book.labels.resize(values.size());
    for (std::size_t i = 0; i < values.size(); ++i) book.labels[i] = nearestEntry(book.entries, values[i]);
    return book;
}

std::size_t paletteSize(std::size_t n, std::size_t cap)
{
    // min(64, 2^floor(log2(n / 1024))) x 1024 is the largest power of two <= n, at most 65536.
    std::size_t k = 1;
    while (k * 2 <= std::min<std::size_t>(n, 64 * 1024)) k *= 2;
    return std::max<std::size_t>(1, std::min(k, cap));
}

std::pair<int, int> imageSize(std::size_t n)
{
    const int w = int(std::ceil(std::sqrt(double(n)) / 4.0)) * 4;
    const int h = int(std::ceil(double(n) / double(std::max(w, 1)) / 4.0)) * 4;
    return {std::max(w, 4), std::max(h, 4)};
}

} // namespace splatwarp::sog
