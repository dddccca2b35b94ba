#include "stage2/SampleBlocks.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "core/Error.h"
#include "core/ParallelFor.h"

namespace splatwarp {
namespace {

/// Block b's slots (samples first[b] .. first[b+1]-1 of x, padding repeating the last), bounds
/// and chunk rows, into arrays sized by build().
void fillBlock(SampleBlocks& b, const float* x, std::size_t k)
{
    const std::size_t begin = b.first[k], end = b.first[k + 1], s0 = b.slot[k], lanes = b.slot[k + 1] - s0;
    float lo[3] = {x[3 * begin], x[3 * begin + 1], x[3 * begin + 2]}, hi[3] = {lo[0], lo[1], lo[2]};
    for (std::size_t t = 0; t < lanes; ++t) {
        const std::size_t j = std::min(begin + t, end - 1); // padding repeats the last sample
        b.px[s0 + t] = x[3 * j];
        b.py[s0 + t] = x[3 * j + 1];
        b.pz[s0 + t] = x[3 * j + 2];
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], x[3 * j + std::size_t(a)]);
            hi[a] = std::max(hi[a], x[3 * j + std::size_t(a)]);
        }
    }
    float* chunks = b.chunks.data() + k * 6 * kChunkSlots; // [6][kChunkSlots]
    for (int c = 0; c < kChunkSlots; ++c)
        for (int a = 0; a < 3; ++a) {
            chunks[a * kChunkSlots + c] = std::numeric_limits<float>::quiet_NaN(); // never meets a Gaussian
            chunks[(3 + a) * kChunkSlots + c] = 0.0f;
        }
    for (std::size_t c = 0; c < lanes / kSimdLanes; ++c) {
        const float* axes[3] = {b.px.data() + s0 + c * kSimdLanes, b.py.data() + s0 + c * kSimdLanes,
                                b.pz.data() + s0 + c * kSimdLanes};
        for (int a = 0; a < 3; ++a) {
            const float cl = *std::min_element(axes[a], axes[a] + kSimdLanes);
            const float ch = *std::max_element(axes[a], axes[a] + kSimdLanes);
            // Rounded outwards: centre +- half holds [cl, ch].
            const float centre = 0.5f * (cl + ch);
            chunks[a * kChunkSlots + c] = centre;
            chunks[(3 + a) * kChunkSlots + c] =
                std::nextafter(std::max(ch - centre, centre - cl), std::numeric_limits<float>::infinity());
        }
    }
    std::copy(lo, lo + 3, b.lo.begin() + std::ptrdiff_t(3 * k));
    std::copy(hi, hi + 3, b.hi.begin() + std::ptrdiff_t(3 * k));
}

} // namespace

SampleBlocks SampleBlocks::build(const float* x, const std::int32_t* cell, std::size_t s, bool threaded)
{
    // The cuts first (runs of equal cell, split every kMaxBlockSamples), then the blocks filled in parallel.
    SampleBlocks b;
    b.first.push_back(0);
    b.slot.push_back(0);
    std::size_t begin = 0;
    for (std::size_t j = 1; j <= s; ++j)
        if (j == s || cell[j] != cell[begin] || j - begin == std::size_t(kMaxBlockSamples)) {
            b.first.push_back(std::uint32_t(j));
            b.slot.push_back(b.slot.back() + std::uint32_t((j - begin + kSimdLanes - 1) / kSimdLanes * kSimdLanes));
            begin = j;
        }
    const std::size_t nb = b.count();
    b.px.resize(b.slot.back());
    b.py.resize(b.slot.back());
    b.pz.resize(b.slot.back());
    b.chunks.resize(nb * 6 * kChunkSlots);
    b.lo.resize(3 * nb);
    b.hi.resize(3 * nb);
    parallelFor(nb, 256, threaded, [&](std::size_t k) { fillBlock(b, x, k); });
    return b;
}

bool boxMeetsSlabs(const float* lo, const float* hi, const CoverageSlabs& slabs)
{
    for (int a = 0; a < 3; ++a) {
        double centre = 0, reach = 0;
        for (int k = 0; k < 3; ++k) {
            const double n = slabs.axis[a][k];
            centre += n * (0.5 * (double(lo[k]) + double(hi[k])) - double(slabs.centre[k]));
            reach += std::fabs(n) * 0.5 * (double(hi[k]) - double(lo[k]));
        }
        // The slab test in Coverage is float arithmetic; a relative allowance keeps this a superset.
        if (!(std::fabs(centre) - reach <= double(slabs.half[a]) * (1 + 1e-6) + 1e-6 * reach)) return false;
    }
    return true;
}

namespace {

bool finiteBox(const float* lo, const float* hi)
{
    for (int a = 0; a < 3; ++a)
        if (!std::isfinite(lo[a]) || !std::isfinite(hi[a])) return false;
    return true;
}

} // namespace

BlockIndex::BlockIndex(const SampleBlocks& blocks)
{
    const std::size_t nb = blocks.count();
    // Cells about as wide as the median block (coarser while the grid would hold more than 8
    // cells a block, or the lists more than kEntriesPerBlock entries a block): a query visits the
    // few cells its own box overlaps, whatever the size of the largest block.
    constexpr double kEntriesPerBlock = 16.0;
    std::vector<float> edges;
    std::vector<std::uint8_t> finite(nb);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (std::size_t b = 0; b < nb; ++b) {
        const float* bl = blocks.lo.data() + 3 * b;
        const float* bh = blocks.hi.data() + 3 * b;
        finite[b] = finiteBox(bl, bh); // not listed otherwise: a block with no finite bounds never meets a Gaussian
        if (!finite[b]) continue;
        edges.push_back(std::max({bh[0] - bl[0], bh[1] - bl[1], bh[2] - bl[2]}));
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], double(bl[a]));
            hi[a] = std::max(hi[a], double(bh[a]));
        }
    }
    if (edges.empty()) return;
    std::nth_element(edges.begin(), edges.begin() + std::ptrdiff_t(edges.size() / 2), edges.end());
    mCell = double(edges[edges.size() / 2]);
    if (!(mCell > 0.0) || !std::isfinite(mCell)) mCell = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1.0});
    for (int a = 0; a < 3; ++a) mLo[a] = lo[a];
    const double cellLimit = std::max(8.0 * double(nb), 4096.0), entryLimit = kEntriesPerBlock * double(nb) + 4096.0;
    for (;;) {
        double cells = 1;
        for (int a = 0; a < 3; ++a) cells *= std::floor((hi[a] - lo[a]) / mCell) + 1;
        if (cells <= cellLimit) {
            for (int a = 0; a < 3; ++a) mCount[a] = std::int64_t(std::floor((hi[a] - lo[a]) / mCell)) + 1;
            double entries = 0;
            for (std::size_t b = 0; b < nb; ++b)
                if (finite[b]) entries += double(cellsOf(blocks, b));
            if (entries <= entryLimit) break;
        }
        mCell *= 2.0;
    }
    // A counting sort: each block in every cell its bounds overlap, ascending within a cell's
    // group; a cell's groups by which of its axes the block starts on (mask bit a: the block's
    // lowest cell along a is this one), so a query reads each block once (blocksMeeting()).
    mStart.assign(std::size_t(mCount[0] * mCount[1] * mCount[2]) * kGroups + 1, 0);
    const auto forEachCell = [&](std::size_t b, auto&& f) {
        std::int64_t c0[3], c1[3];
        cellRange(blocks.lo.data() + 3 * b, blocks.hi.data() + 3 * b, c0, c1);
        for (std::int64_t i = c0[0]; i <= c1[0]; ++i)
            for (std::int64_t j = c0[1]; j <= c1[1]; ++j)
                for (std::int64_t k = c0[2]; k <= c1[2]; ++k) {
                    const std::size_t mask = std::size_t(i == c0[0]) | std::size_t(j == c0[1]) << 1 | std::size_t(k == c0[2]) << 2;
                    f(std::size_t((i * mCount[1] + j) * mCount[2] + k) * kGroups + mask);
                }
    };
    for (std::size_t b = 0; b < nb; ++b)
        if (finite[b]) forEachCell(b, [&](std::size_t g) { ++mStart[g + 1]; });
    for (std::size_t g = 1; g < mStart.size(); ++g) mStart[g] += mStart[g - 1];
    std::vector<std::uint32_t> next(mStart.begin(), mStart.end() - 1);
    mItems.resize(mStart.back());
    for (std::size_t b = 0; b < nb; ++b)
        if (finite[b]) forEachCell(b, [&](std::size_t g) { mItems[next[g]++] = std::uint32_t(b); });
}

double BlockIndex::cellsOf(const SampleBlocks& blocks, std::size_t b) const
{
    std::int64_t c0[3], c1[3];
    if (!cellRange(blocks.lo.data() + 3 * b, blocks.hi.data() + 3 * b, c0, c1)) return 0.0;
    return double(c1[0] - c0[0] + 1) * double(c1[1] - c0[1] + 1) * double(c1[2] - c0[2] + 1);
}

std::int64_t BlockIndex::cellOf(double x, int a) const
{
    const double c = std::floor((x - mLo[a]) / mCell);
    return c < 0 ? 0 : c > double(mCount[a] - 1) ? mCount[a] - 1 : std::int64_t(c);
}

bool BlockIndex::cellRange(const float* lo, const float* hi, std::int64_t* c0, std::int64_t* c1) const
{
    if (mCount[0] == 0) return false;
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(lo[a]) || !std::isfinite(hi[a])) return false; // a non-finite box lists nothing
        const double l = std::floor((double(lo[a]) - mLo[a]) / mCell), h = std::floor((double(hi[a]) - mLo[a]) / mCell);
        if (!(h >= 0 && l <= double(mCount[a] - 1))) return false;
        c0[a] = cellOf(double(lo[a]), a);
        c1[a] = cellOf(double(hi[a]), a);
    }
    return true;
}

void BlockIndex::blocksMeeting(const SampleBlocks& blocks, const float* lo, const float* hi, const CoverageSlabs* slabs,
                               std::vector<std::uint32_t>& out) const
{
    out.clear();
    if (!(hi[0] >= lo[0] && hi[1] >= lo[1] && hi[2] >= lo[2])) return; // empty (or NaN): never counts
    std::int64_t c0[3], c1[3];
    if (mItems.empty() || !cellRange(lo, hi, c0, c1)) return;
    for (std::int64_t i = c0[0]; i <= c1[0]; ++i)
        for (std::int64_t j = c0[1]; j <= c1[1]; ++j)
            for (std::int64_t k = c0[2]; k <= c1[2]; ++k) {
                // A block meeting the box is read once: in the cell of the overlap's lower corner,
                // on each axis the later of the box's first cell and the block's (cellOf is
                // monotone). Past the box's first cell along an axis, that is the block's first
                // cell: only the groups of blocks starting there along every such axis are read.
                const std::size_t need = std::size_t(i > c0[0]) | std::size_t(j > c0[1]) << 1 | std::size_t(k > c0[2]) << 2;
                const std::size_t c = std::size_t((i * mCount[1] + j) * mCount[2] + k) * kGroups;
                for (std::size_t mask = need; mask < kGroups; mask = (mask + 1) | need) {
                    // No branch on the test (a candidate meets the box about as often as not,
                    // which the predictor cannot learn): each is written, the count advances on a
                    // hit; the slabs, costlier and rarer, are tested after on the hits only.
                    const std::uint32_t e0 = mStart[c + mask], e1 = mStart[c + mask + 1];
                    std::size_t n = out.size();
                    out.resize(n + (e1 - e0));
                    for (std::uint32_t e = e0; e < e1; ++e) {
                        const std::uint32_t b = mItems[e];
                        const float* bl = blocks.lo.data() + 3 * std::size_t(b);
                        const float* bh = blocks.hi.data() + 3 * std::size_t(b);
                        const bool miss = (bh[0] < lo[0]) | (bl[0] > hi[0]) | (bh[1] < lo[1]) | (bl[1] > hi[1]) |
                                          (bh[2] < lo[2]) | (bl[2] > hi[2]);
                        out[n] = b;
                        n += !miss;
                    }
                    out.resize(n);
                }
            }
    if (slabs)
        out.erase(std::remove_if(out.begin(), out.end(),
                                 [&](std::uint32_t b) {
                                     return !boxMeetsSlabs(blocks.lo.data() + 3 * std::size_t(b),
                                                           blocks.hi.data() + 3 * std::size_t(b), *slabs);
                                 }),
                  out.end());
}

std::uint64_t coveragePairLimit(std::size_t budget, double used, double bytesEach)
{
    if (budget == 0) return kMaxCoveragePairs;
    const double room = double(budget) - used;
    if (!(room > 0) || !(bytesEach > 0)) return 0;
    return std::uint64_t(std::min(double(kMaxCoveragePairs), std::floor(room / bytesEach)));
}

InputError coverageTooLarge(const std::string& stage, std::uint64_t limit, double bytesEach, const std::string& room,
                            const std::string& advice)
{
    const std::string why = limit >= kMaxCoveragePairs ? std::string("too many for 32-bit indices")
                                                       : msg(formatBytes(bytesEach), " each: more than fit in ", room);
    return InputError(msg(stage, ": the Gaussians reach more than ", limit, " (block, Gaussian) pairs of samples (", why,
                          "). ", advice.empty() ? std::string(kCoverageAdvice) : advice));
}

bool BlockCoverage::build(const float* lo, const float* hi, const CoverageSlabs* slabs, std::size_t g, bool threaded,
                          const std::uint8_t* keep, std::uint64_t maxPairs)
{
    // Gaussian-major: each Gaussian asks the block index (built once: blocks never move) for the
    // blocks its box and slabs meet. The per-block search it replaces tested ~8 scattered
    // Gaussians per pair kept (donut: 47 M candidates for 7 M pairs).
    if (!mBlocks) throw Error("BlockCoverage::build without blocks");
    const SampleBlocks& blocks = *mBlocks;
    if (mPerGaussian.size() != g) keep = nullptr;
    mPerGaussian.resize(g);
    // The pairs so far, counted as the lists are found, so that a coverage past the limit stops
    // while its lists are still within it (a model of giants reaches billions: killed at 24 GB).
    maxPairs = std::min(maxPairs, kMaxCoveragePairs);
    std::uint64_t kept = 0;
    if (keep)
        for (std::size_t k = 0; k < g; ++k) kept += keep[k] ? mPerGaussian[k].size() : 0;
    std::atomic<std::uint64_t> pairs{kept};
    std::atomic<bool> over{kept > maxPairs};
    parallelForRange(g, 64, threaded, [&](std::size_t k0, std::size_t k1) {
        // Found into scratch, then copied: one allocation of the right size per Gaussian (growing
        // 42k lists by push_back cost the donut's first build ~10 reallocations each).
        std::vector<std::uint32_t> found;
        for (std::size_t k = k0; k < k1 && !over.load(std::memory_order_relaxed); ++k) {
            if (keep && keep[k]) continue;
            mIndex.blocksMeeting(blocks, lo + 3 * k, hi + 3 * k, slabs ? slabs + k : nullptr, found);
            if (pairs.fetch_add(found.size(), std::memory_order_relaxed) + found.size() > maxPairs) {
                over.store(true, std::memory_order_relaxed);
                break;
            }
            std::sort(found.begin(), found.end());
            mPerGaussian[k].assign(found.begin(), found.end());
        }
    });
    if (over.load()) {
        clear();
        return false;
    }
    flatten(blocks.count(), g, threaded);
    return true;
}

void BlockCoverage::clear()
{
    std::vector<std::vector<std::uint32_t>>().swap(mPerGaussian);
    mGaussianOffsets.clear();
    mBlockOffsets.clear();
    BigVector<std::uint32_t>().swap(mBlockItems);
    BigVector<std::uint32_t>().swap(mBlockEntryOf);
}

void BlockCoverage::flatten(std::size_t nb, std::size_t g, bool threaded)
{
    // Each Gaussian's blocks ascend (build()); the block-major lists come by a counting sort over
    // kRanges ranges of Gaussians at once (each range's entries after the earlier ranges' in
    // every block), so each block's Gaussians ascend whatever the thread count.
    constexpr std::size_t kRanges = 8;
    mGaussianOffsets.assign(g + 1, 0);
    for (std::size_t k = 0; k < g; ++k) mGaussianOffsets[k + 1] = mGaussianOffsets[k] + mPerGaussian[k].size();
    const std::uint64_t pairs = mGaussianOffsets[g]; // at most kMaxCoveragePairs (build())
    const auto rangeOf = [&](std::size_t r) { return std::make_pair(g * r / kRanges, g * (r + 1) / kRanges); };
    std::vector<std::uint32_t> start(kRanges * nb, 0); // [range][block] entries, then where each range starts
    parallelFor(kRanges, 1, threaded, [&](std::size_t r) {
        for (std::size_t k = rangeOf(r).first; k < rangeOf(r).second; ++k)
            for (const std::uint32_t b : mPerGaussian[k]) ++start[r * nb + b];
    });
    mBlockOffsets.assign(nb + 1, 0);
    for (std::size_t b = 0; b < nb; ++b) {
        std::uint64_t at = mBlockOffsets[b];
        for (std::size_t r = 0; r < kRanges; ++r) {
            const std::uint32_t n = start[r * nb + b];
            start[r * nb + b] = std::uint32_t(at);
            at += n;
        }
        mBlockOffsets[b + 1] = at;
    }
    resizeDiscarding(mBlockItems, pairs); // every entry is written below
    resizeDiscarding(mBlockEntryOf, pairs);
    parallelFor(kRanges, 1, threaded, [&](std::size_t r) {
        for (std::size_t k = rangeOf(r).first; k < rangeOf(r).second; ++k) {
            std::uint32_t* entryOf = mBlockEntryOf.data() + mGaussianOffsets[k];
            for (const std::uint32_t b : mPerGaussian[k]) {
                const std::uint32_t e = start[r * nb + b]++;
                mBlockItems[e] = std::uint32_t(k);
                *entryOf++ = e;
            }
        }
    });
}

} // namespace splatwarp
