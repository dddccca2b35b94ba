/// `splatwarp convert IN OUT.ply [--drop-invalid]`: any supported input to graphdeco PLY.
#include "Command.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "io/GaussianIO.h"

namespace splatwarp::cli {
namespace {

struct ConvertArgs {
    std::string input, output;
    ReadOptions options;
};

const CommandRegistrar reg(21, [](CLI::App& app) {
    auto args = std::make_shared<ConvertArgs>();
    CLI::App* sub = app.add_subcommand(
        "convert", "Convert a Gaussian file (any PLY layout, compressed PLY, .splat, .spz) to graphdeco binary PLY");
    sub->add_option("input", args->input, "Input Gaussian file (format detected from the content)")->required();
    sub->add_option("output", args->output, "Output graphdeco .ply path (written atomically)")->required();
    sub->add_flag("--drop-invalid", args->options.dropInvalid,
                  "Drop Gaussians with NaN/Inf values (default: refuse the file)");
    sub->callback([args] {
        ReadReport report;
        const GaussianCloud g = readGaussians(args->input, args->options, &report);
        for (const std::string& note : report.notes) progress(args->input + ": " + note);
        writePly(args->output, g);
        progress(msg("converted ", g.size(), " Gaussians (", report.format, ", SH degree ", g.shDegree, ") to ",
                     args->output));
    });
});

} // namespace
} // namespace splatwarp::cli
