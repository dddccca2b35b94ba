#pragma once
/// @file GridArgs.h
/// @brief The sample-grid flags of `to-vdb` and `eval` (their help is the deform settings table's,
///        job/DeformSettings.h, whose rows are deform's flags).
#include <string>

#include "Command.h"
#include "SharedArgs.h"
#include "job/DeformSettings.h"
#include "vdb/SampleGrid.h"

namespace splatwarp::cli {

/// `grid.samplesPerAxis` on entry is the default of --samples-per-cell (kAutoSamplesPerAxis: auto).
inline void addGridOptions(CLI::App* sub, SampleGridOptions& grid)
{
    sub->add_option("--cells", grid.cells, deformSetting("--cells").help)
        ->capture_default_str()
        ->check(positive());
    sub->add_option("--cell-size", grid.cellSize, deformSetting("--cell-size").help)
        ->check(positive());
    sub->add_option_function<std::string>(
           "--samples-per-cell",
           [&grid](const std::string& word) {
               grid.samplesPerAxis = word == "auto" ? kAutoSamplesPerAxis : std::stoi(word); // checked below
           },
           deformSetting("--samples-per-cell").help)
        ->type_name("auto|N")
        ->default_str(grid.samplesPerAxis == kAutoSamplesPerAxis ? "auto" : std::to_string(grid.samplesPerAxis))
        ->check(autoOrWholeNumber(2, 16, ""));
    sub->add_option("--cutoff", grid.cutoff, deformSetting("--cutoff").help)
        ->capture_default_str()
        ->check(inRange(1e-8, 0.999));
    addMaxMemoryOption(sub, grid.maxMemoryBytes, deformSetting("--max-memory").help);
}

} // namespace splatwarp::cli
