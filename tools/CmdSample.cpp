/// `splatwarp sample NAME -o OUT.ply`: write a procedural sample model.
#include "Command.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "core/AtomicFile.h"
#include "io/GaussianIO.h"
#include "demo/DemoModels.h"

namespace splatwarp::cli {
namespace {

struct SampleArgs {
    std::string name, output;
    DemoModelOptions options;
};

const CommandRegistrar reg(10, [](CLI::App& app) {
    auto args = std::make_shared<SampleArgs>();
    CLI::App* sub = app.add_subcommand("sample", "Generate a procedural sample model (stripes, ring) as graphdeco PLY");
    sub->add_option("name", args->name, "Sample name: stripes (4x1x1 bar, 8 colour bands, SH1) or ring (torus, SH0)")
        ->required()
        ->check(CLI::IsMember(demoModelNames()));
    sub->add_option("-o,--output", args->output, "Output .ply path")->required();
    sub->add_option("--count", args->options.count, "Number of Gaussians, at least 1 (default: stripes 20000, ring 16000)")
        ->check(CLI::Range(std::size_t(1), std::size_t(1) << 40));
    sub->add_option("--seed", args->options.seed, "Random seed (deterministic output per seed)")->capture_default_str();
    sub->callback([args] {
        if (outputFormatOf(args->output) != "ply") // it wrote PLY bytes under x.splat
            throw UsageError(msg("sample writes graphdeco PLY: name the output *.ply, not ", args->output,
                                 " (convert writes the other formats)"));
        OutputSet outputs;
        outputs.checkTarget(args->output);
        const GaussianCloud g = makeDemoModel(args->name, args->options);
        writePly(args->output, g);
        outputs.commit();
        progress(msg("wrote ", g.size(), " Gaussians (SH degree ", g.shDegree, ") to ", args->output));
    });
});

} // namespace
} // namespace splatwarp::cli
