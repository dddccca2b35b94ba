#pragma once
// The active cells of a SampleGrid as a plain map from integer cell coordinates to the cell
// index (-1: not active), built from SampleGrid::cellCoords(): an independent reference for the
// grid's OpenVDB and NanoVDB index grids.
#include <cstdint>
#include <map>
#include <tuple>

#include "vdb/SampleGrid.h"

namespace splatwarp::test {

class CellLookup {
public:
    explicit CellLookup(const SampleGrid& grid)
    {
        const std::vector<std::int32_t>& ijk = grid.cellCoords();
        for (std::size_t c = 0; c < ijk.size() / 3; ++c)
            mIndex[{ijk[3 * c], ijk[3 * c + 1], ijk[3 * c + 2]}] = std::int32_t(c);
    }
    std::int32_t operator()(int i, int j, int k) const
    {
        const auto it = mIndex.find({i, j, k});
        return it == mIndex.end() ? -1 : it->second;
    }

private:
    std::map<std::tuple<int, int, int>, std::int32_t> mIndex;
};

} // namespace splatwarp::test
