/// `splatwarp convert IN OUT.ply [--drop-invalid]`: any supported input to graphdeco PLY.
#include "Command.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "core/AtomicFile.h"
#include "io/GaussianIO.h"
#include "ReadArgs.h"

namespace splatwarp::cli {
namespace {

struct ConvertArgs {
    std::string input, output;
    bool dropInvalid = false;
};

const CommandRegistrar reg(21, [](CLI::App& app) {
    auto args = std::make_shared<ConvertArgs>();
    CLI::App* sub = app.add_subcommand(
        "convert", "Convert a Gaussian file (any PLY layout, compressed PLY, .splat, .spz) to graphdeco binary PLY");
    sub->add_option("input", args->input, "Input Gaussian file (format detected from the content)")->required();
    sub->add_option("output", args->output, "Output graphdeco .ply path (written atomically)")->required();
    addDropInvalidFlag(sub, args->dropInvalid);
    sub->callback([args] {
        OutputSet outputs({args->input});
        outputs.checkTarget(args->output);
        ReadReport report;
        const GaussianCloud g = readModel(args->input, args->dropInvalid, &report);
        writePly(args->output, g);
        outputs.commit();
        progress(msg("converted ", g.size(), " Gaussians (", report.format, ", SH degree ", g.shDegree, ") to ",
                     args->output));
    });
});

} // namespace
} // namespace splatwarp::cli
