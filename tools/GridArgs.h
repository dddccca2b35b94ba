#pragma once
/// @file GridArgs.h
/// @brief The sample-grid flags shared by `to-vdb`, `deform` and `eval` (one definition).
#include "Command.h"
#include "SampleGrid.h"
#include "core/Memory.h"

namespace splatwarp::cli {

inline void addGridOptions(CLI::App* sub, SampleGridOptions& grid)
{
    sub->add_option("--cells", grid.cells, "Cells along the model's largest extent (ignored with --cell-size)")
        ->capture_default_str()
        ->check(positive());
    sub->add_option("--cell-size", grid.cellSize, "Explicit cell edge in world units (overrides --cells)")
        ->check(positive());
    sub->add_option("--samples-per-cell", grid.samplesPerAxis, "Samples per cell along each axis (n; n^3 per cell)")
        ->capture_default_str()
        ->check(inRange(2, 16));
    sub->add_option("--cutoff", grid.cutoff, "A Gaussian contributes where alpha*G >= cutoff (1e-3 for thin structures)")
        ->capture_default_str()
        ->check(inRange(1e-8, 0.999));
    grid.maxMemoryBytes = defaultMemoryBudget();
    sub->add_option_function<std::string>(
           "--max-memory", [&grid](const std::string& text) { grid.maxMemoryBytes = parseByteSize(text, "--max-memory"); },
           "Refuse a job whose sample grid (and Stage II) would need more host memory than this, estimated before "
           "allocating: 8G, 512M, ... (default: 3/4 of physical memory, " + formatBytes(double(grid.maxMemoryBytes)) + " here)")
        ->type_name("SIZE");
}

} // namespace splatwarp::cli
