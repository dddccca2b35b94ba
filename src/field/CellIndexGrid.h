#pragma once
/// @file CellIndexGrid.h
/// @brief The SampleGrid's cell index grid (cell coordinate -> cell index, background -1) as a
///        NanoVDB Int32 grid held in plain bytes, so the core library and the CUDA kernels can
///        use it without OpenVDB (vdb/SampleGrid converts it; field/CellTargetMath.h reads it).
#include <cstddef>
#include <cstring>
#include <vector>

namespace splatwarp {

/// @brief A serialised NanoVDB grid (one GridHandle's buffer), 32-byte aligned as NanoVDB requires.
class CellIndexGrid {
public:
    /// @brief Copy a NanoVDB grid buffer of `bytes` bytes.
    void assign(const void* data, std::size_t bytes)
    {
        mStorage.assign((bytes + sizeof(Block) - 1) / sizeof(Block), Block{});
        if (bytes) std::memcpy(mStorage.data(), data, bytes);
        mBytes = bytes;
    }
    const void* data() const { return mStorage.data(); }
    std::size_t bytes() const { return mBytes; }
    bool empty() const { return mBytes == 0; }

private:
    /// NANOVDB_DATA_ALIGNMENT is 32; std::vector honours alignas through C++17 aligned new.
    struct alignas(32) Block {
        unsigned char b[32];
    };
    std::vector<Block> mStorage;
    std::size_t mBytes = 0;
};

} // namespace splatwarp
