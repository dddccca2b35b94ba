#pragma once
/// @file GridArgs.h
/// @brief The sample-grid flags shared by `to-vdb`, `deform` and `eval` (one definition).
#include "Command.h"
#include "SampleGrid.h"

namespace splatwarp::cli {

inline void addGridOptions(CLI::App* sub, SampleGridOptions& grid)
{
    sub->add_option("--cells", grid.cells, "Cells along the model's largest extent (ignored with --cell-size)")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    sub->add_option("--cell-size", grid.cellSize, "Explicit cell edge in world units (overrides --cells)")
        ->check(CLI::PositiveNumber);
    sub->add_option("--samples-per-cell", grid.samplesPerAxis, "Samples per cell along each axis (n; n^3 per cell)")
        ->capture_default_str()
        ->check(CLI::Range(2, 16));
    sub->add_option("--cutoff", grid.cutoff, "A Gaussian contributes where alpha*G >= cutoff (1e-3 for thin structures)")
        ->capture_default_str()
        ->check(CLI::Range(1e-8, 0.999));
}

/// @brief `--device auto|cpu|cuda` (default auto); `what` says what runs there ("the rest
///        targets run"). The callback parses it with parseDevice().
inline void addDeviceOption(CLI::App* sub, std::string& device, const std::string& what)
{
    sub->add_option("--device", device,
                    "Where " + what + ": auto (CUDA when compiled in and a GPU is present, else CPU), cpu or cuda")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
}

} // namespace splatwarp::cli
