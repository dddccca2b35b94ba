#pragma once
/// @file SampleBlocks.h
/// @brief Stage II's samples grouped into blocks and the coverage between blocks and Gaussians.
///        A block is a run of consecutive used samples of one cell (at most kMaxBlockSamples):
///        a cell's n^3 warped samples are spatially coherent, so a (block, Gaussian) list is
///        about n^3 times shorter than a (sample, Gaussian) one, and the pair work runs over a
///        block's samples contiguously, kSimdLanes at a time (structure of arrays, padded).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/Error.h"
#include "core/Memory.h"
#include "core/Simd.h"
#include "stage2/Coverage.h"

namespace splatwarp {

/// Largest block: a cell of 4^3 samples (the default) is one block; larger cells are split.
constexpr int kMaxBlockSamples = 64;
/// Chunks of kSimdLanes slots in a block at most: one SIMD register holds one value of each.
constexpr int kChunkSlots = kMaxBlockSamples / kSimdLanes;
static_assert(kChunkSlots == kSimdLanes, "the chunk tests run on one register");

/// @brief Used samples in padded blocks (structure of arrays).
struct SampleBlocks {
    std::vector<std::uint32_t> first; ///< [B+1] first used sample of each block (block b: first[b] .. first[b+1]-1)
    std::vector<std::uint32_t> slot;  ///< [B+1] first padded slot; slot[b+1] - slot[b] is a multiple of kSimdLanes
    std::vector<float> px, py, pz;    ///< [P] positions per slot; padding repeats the block's last sample
    std::vector<float> lo, hi;        ///< [B,3] bounds of each block's samples
    /// [B, 6, kChunkSlots]: per block its chunks' (kSimdLanes slots each) centres x, y, z and half
    /// sizes x, y, z, each a row of kChunkSlots; unused chunk slots have NaN centres.
    std::vector<float> chunks;

    std::size_t count() const { return first.empty() ? 0 : first.size() - 1; }
    std::size_t slots() const { return px.size(); }
    int samplesOf(std::size_t b) const { return int(first[b + 1] - first[b]); }
    int lanesOf(std::size_t b) const { return int(slot[b + 1] - slot[b]); }
    const float* chunksOf(std::size_t b) const { return chunks.data() + b * 6 * kChunkSlots; }

    /// @brief Blocks of s samples at positions x [s,3] whose cells are cell [s] (runs of equal
    ///        cell in this order, split every kMaxBlockSamples).
    static SampleBlocks build(const float* x, const std::int32_t* cell, std::size_t s, bool threaded = true);
};

/// @brief The blocks of a SampleBlocks binned by their centres, for finding the blocks a box meets.
class BlockIndex {
public:
    BlockIndex() = default;
    explicit BlockIndex(const SampleBlocks& blocks);

    /// @brief The blocks whose bounds meet the box [lo, hi] and (when given) the slabs, into out
    ///        (in no particular order). An empty or non-finite box meets none.
    void blocksMeeting(const SampleBlocks& blocks, const float* lo, const float* hi, const CoverageSlabs* slabs,
                       std::vector<std::uint32_t>& out) const;

private:
    /// The cells c0[a]..c1[a] along each axis a that [lo, hi] overlaps; false when it misses the
    /// grid or is not finite.
    bool cellRange(const float* lo, const float* hi, std::int64_t* c0, std::int64_t* c1) const;
    /// The cell along axis a holding x, clamped to the grid (monotone in x).
    std::int64_t cellOf(double x, int a) const;
    /// How many cells block b's bounds overlap.
    double cellsOf(const SampleBlocks& blocks, std::size_t b) const;

    // Each block listed in every cell of a dense grid its bounds overlap (no search per cell,
    // unlike sparse bins; no padding by the largest block, unlike binning centres): group m of
    // cell c (i, j, k) holds mItems[mStart[8c + m], mStart[8c + m + 1]).
    double mLo[3] = {0, 0, 0};
    double mCell = 1.0;
    std::int64_t mCount[3] = {0, 0, 0};
    static constexpr std::size_t kGroups = 8; ///< per cell, by the axes its blocks start on
    std::vector<std::uint32_t> mStart, mItems;
};

/// The most (block, Gaussian) pairs a coverage holds: its entries are 32-bit indices.
constexpr std::uint64_t kMaxCoveragePairs = 0xffffffffull;
/// Bytes a pair takes in a coverage: its Gaussian's list and the two block-major lists.
constexpr std::size_t kCoveragePairBytes = 3 * sizeof(std::uint32_t);

/// @brief The most pairs of bytesEach that fit in what `budget` bytes leave beside `used` (none
///        where nothing is left), at most kMaxCoveragePairs; budget 0: no limit but that one.
std::uint64_t coveragePairLimit(std::size_t budget, double used, double bytesEach);

/// @brief What a coverage past its limit tells deform's and to-vdb's users to change.
constexpr const char* kCoverageAdvice = "Gaussians far wider than the model do this (`splatwarp info` warns of them); "
                                        "lower --cells, or raise --max-memory if the machine has more";

/// @brief The error of a coverage past its limit (coveragePairLimit()); `room` names the memory
///        that set it ("the 2 GiB that --max-memory 8 GiB leaves ..."), `advice` what to change
///        (kCoverageAdvice: deform's and to-vdb's).
InputError coverageTooLarge(const std::string& stage, std::uint64_t limit, double bytesEach, const std::string& room,
                            const std::string& advice = kCoverageAdvice);

/// @brief Which blocks each moving Gaussian may touch, and the reverse, both lists ascending so
///        every sum runs in a fixed order for any thread count.
class BlockCoverage {
public:
    BlockCoverage() = default;
    /// @brief Coverage over these blocks (kept by reference: they must outlive it and never
    ///        move, as within a Stage II run); their centres are indexed once, here.
    explicit BlockCoverage(const SampleBlocks& blocks) : mBlocks(&blocks), mIndex(blocks) {}

    /// @param lo,hi  [g,3] padded coverage boxes (empty, hi < lo: nothing)
    /// @param slabs  [g] coverage slabs (a block must also meet all three)
    /// @param keep   [g] or null: where set, the Gaussian keeps its blocks of the last build (of
    ///               the same g)
    /// @param maxPairs  the most pairs it may hold (at most kMaxCoveragePairs)
    /// @return false when the pairs would pass maxPairs: the build stops as soon as they do, before
    ///         the block-major lists are allocated, and the coverage is left empty
    [[nodiscard]] bool build(const float* lo, const float* hi, const CoverageSlabs* slabs, std::size_t g, bool threaded,
                             const std::uint8_t* keep = nullptr, std::uint64_t maxPairs = kMaxCoveragePairs);

    std::uint64_t pairCount() const { return mBlockItems.size(); }
    /// @brief Pairs of Gaussian k: blockEntryOf()[gaussianOffsets()[k] .. gaussianOffsets()[k+1]).
    const std::vector<std::uint64_t>& gaussianOffsets() const { return mGaussianOffsets; }
    /// @brief Gaussians of block b, ascending.
    const std::vector<std::uint64_t>& blockOffsets() const { return mBlockOffsets; }
    const BigVector<std::uint32_t>& blockItems() const { return mBlockItems; }
    /// @brief Per Gaussian, its pairs' entries in blockItems(), in ascending block order.
    const BigVector<std::uint32_t>& blockEntryOf() const { return mBlockEntryOf; }

private:
    void flatten(std::size_t nb, std::size_t g, bool threaded);
    void clear();

    const SampleBlocks* mBlocks = nullptr;
    BlockIndex mIndex; ///< of *mBlocks
    std::vector<std::vector<std::uint32_t>> mPerGaussian; ///< per Gaussian its blocks, reused between rebuilds
    std::vector<std::uint64_t> mGaussianOffsets, mBlockOffsets;
    BigVector<std::uint32_t> mBlockItems, mBlockEntryOf;
};

/// @brief Whether the box [lo, hi] can hold a point inside all three slabs (conservative: the
///        box's projection on each slab axis meets the slab).
bool boxMeetsSlabs(const float* lo, const float* hi, const CoverageSlabs& slabs);

} // namespace splatwarp
