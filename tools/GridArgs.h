#pragma once
/// @file GridArgs.h
/// @brief The sample-grid flags shared by `to-vdb`, `deform` and `eval` (one definition).
#include <string>

#include "Command.h"
#include "vdb/SampleGrid.h"
#include "core/Memory.h"

namespace splatwarp::cli {

/// `grid.samplesPerAxis` on entry is the default of --samples-per-cell (kAutoSamplesPerAxis: auto).
inline void addGridOptions(CLI::App* sub, SampleGridOptions& grid)
{
    sub->add_option("--cells", grid.cells, "Cells along the model's largest extent (ignored with --cell-size)")
        ->capture_default_str()
        ->check(positive());
    sub->add_option("--cell-size", grid.cellSize, "Explicit cell edge in world units (overrides --cells)")
        ->check(positive());
    sub->add_option_function<std::string>(
           "--samples-per-cell",
           [&grid](const std::string& word) {
               grid.samplesPerAxis = word == "auto" ? kAutoSamplesPerAxis : std::stoi(word); // checked below
           },
           msg("Samples per cell along each axis (n; n^3 per cell), or auto: the densest n from ", kAutoSamplesMin, " to ",
               kAutoSamplesMax, " whose grid holds at most ", kAutoSampleBudget,
               " samples (and fits --max-memory), counted on the cells at n = ", kAutoSamplesMin,
               ": small models get a finer lattice and filter"))
        ->type_name("auto|N")
        ->default_str(grid.samplesPerAxis == kAutoSamplesPerAxis ? "auto" : std::to_string(grid.samplesPerAxis))
        ->check(autoOrWholeNumber(2, 16, ""));
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
