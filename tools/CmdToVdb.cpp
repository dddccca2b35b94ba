/// `splatwarp to-vdb IN -o OUT.vdb`: sample a model's radiance field into sparse VDB grids.
#include "Command.h"
#include "GridArgs.h"
#include "SharedArgs.h"
#include "vdb/SampleGrid.h"
#include "deform/WarpDevice.h"
#include "vdb/VdbExport.h"
#include "core/Error.h"
#include "core/Memory.h"
#include "core/Progress.h"
#include "deform/DeformSpec.h"
#include "core/AtomicFile.h"
#include "io/GaussianIO.h"
#include "ReadArgs.h"

namespace splatwarp::cli {
namespace {

struct ToVdbArgs {
    std::string input, output, spec;
    Device device = Device::Auto;
    SampleGridOptions grid;
    VdbExportOptions vdb;
    bool dropInvalid = false;
};

const CommandRegistrar reg(40, [](CLI::App& app) {
    auto args = std::make_shared<ToVdbArgs>();
    CLI::App* sub = app.add_subcommand("to-vdb", "Sample a Gaussian model's radiance field into an OpenVDB file "
                                                 "(density fog volume, color, active cells, optional SH grids)");
    sub->add_option("input", args->input, "Input Gaussians " + kModelFormats)->required();
    sub->add_option("-o,--output", args->output, "Output .vdb path")->required();
    addGridOptions(sub, args->grid);
    addDropInvalidFlag(sub, args->dropInvalid);
    addDeviceOption(sub, args->device, "the rest targets and the --spec warping run (topology and export stay on the CPU)");
    sub->add_flag("--sh-grids", args->vdb.shGrids, "Also write one Vec3S grid sh_<k> per SH coefficient of the radial features");
    sub->add_flag("--half", args->vdb.half, "Store float grids as 16-bit half floats");
    sub->add_option("--spec", args->spec,
                    "Deformation spec (JSON): warp the samples and add the per-cell `stretch` grid (largest singular "
                    "value of the cell's deformation gradient); SH grids are then rotated to the warped frame");
    sub->callback([args] {
        args->grid.device = resolveDevice(args->device);
        OutputSet outputs({args->input, args->spec});
        outputs.checkTarget(args->output);
        const GaussianCloud cloud = readModel(args->input, args->dropInvalid);
        progress(msg("read ", cloud.size(), " Gaussians (SH degree ", cloud.shDegree, ") from ", args->input));
        SampleGrid grid = runStage("sample grid", [&] { return SampleGrid(cloud, args->grid); });
        args->vdb.source = args->input;
        if (!args->spec.empty()) {
            const Deformation deformation = solveDeformation(cloud, loadDeformSpec(args->spec));
            progress(msg("solved the deformation of ", args->spec, " (", deformation.graph.nodeCount(), " nodes)"));
            const Device used = warpSamplesOn(grid.samples(), deformation, {args->grid.device});
            progress(msg("warped ", grid.stats().samples, " samples on ", deviceName(used)));
            args->vdb.spec = args->spec;
            args->vdb.stretch = true;
        }
        runStage("VDB export", [&] { writeSampleGridVdb(args->output, grid, args->vdb); });
        outputs.commit();
    });
});

} // namespace
} // namespace splatwarp::cli
