/// `splatwarp convert IN OUT [--points] [--spz-version 3|4] [--sog-*] [--drop-invalid] [--drop-outliers]`: any model read by
/// content to the format OUT's extension names (docs/formats.md).
#include "Command.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Outliers.h"
#include "core/Progress.h"
#include "io/GaussianIO.h"
#include "io/SogIO.h"
#include "ReadArgs.h"

namespace splatwarp::cli {
namespace {

struct ConvertArgs {
    std::string input, output;
    bool dropInvalid = false, dropOutliers = false, points = false;
    int spzVersion = 3;
    SogOptions sog;
    bool spzFlagGiven = false, sogFlagGiven = false; // set from the parse: refused with another format
};

// --sog-seed as a whole number in [0, 2^64 - 1]: CLI11 alone would wrap "-1" and saturate 2^64.
const CLI::Validator kSeedRange(
    [](std::string& s) -> std::string {
        const bool digits = !s.empty() && s.size() <= 20 && s.find_first_not_of("0123456789") == std::string::npos;
        if (digits && (s.size() < 20 || s <= "18446744073709551615")) return {};
        return "must be a whole number in [0, 18446744073709551615], not " + s;
    },
    "UINT64");

/// --drop-outliers: what `info` warns of (core/Outliers.h) removed, and said.
void dropOutliers(const std::string& input, GaussianCloud& g)
{
    const Outliers f = findOutliers(g);
    const std::vector<std::uint8_t> drop = f.either();
    const std::size_t n = g.size();
    g.erase(drop);
    if (g.empty())
        throw InputError(msg(input, ": every one of its ", n, " Gaussians is an outlier (--drop-outliers would leave none)"));
    progress(msg(input, ": dropped ", n - g.size(), " outliers: ", f.farCount, " whose centres lie more than ", f.bulkSize,
                 " units outside the box of the central 98%, ", f.giantCount, " wider than ", kGiantSigma * f.bulkSize,
                 " (a standard deviation)"));
}

void convert(const ConvertArgs& args)
{
    const std::string format = outputFormatOf(args.output);
    if (format == "vdb-points" && !args.points)
        throw UsageError(msg(args.output, ": a .vdb model output is an OpenVDB point grid: add --points "
                                          "(volumes are written by 'to-vdb')"));
    if (args.points && format != "vdb-points") throw UsageError(msg("--points needs a .vdb output, not ", args.output));
    if (args.spzFlagGiven && format != "spz") throw UsageError(msg("--spz-version needs a .spz output, not ", args.output));
    if (args.sogFlagGiven && format != "sog") throw UsageError(msg("--sog-* need a .sog or meta.json output, not ", args.output));
    OutputSet outputs({args.input});
    outputs.checkTarget(args.output);
    ReadReport report;
    GaussianCloud g = readModel(args.input, args.dropInvalid, &report);
    if (args.dropOutliers) dropOutliers(args.input, g);
    WriteOptions options;
    options.spzVersion = args.spzVersion;
    if (format == "sog")
        writeSog(args.output, g, args.sog);
    else
        writeGaussians(args.output, g, options);
    outputs.commit();
    if (format == "splat" && g.shDegree > 0)
        progress(msg("note: .splat holds no SH bands: band", g.shDegree > 1 ? msg("s 1-", g.shDegree) : std::string(" 1"),
                     " dropped (.ply, .spz, .sog and .glb keep them)"));
    progress(msg("converted ", g.size(), " Gaussians (", report.format, ", SH degree ", g.shDegree, ") to ",
                 args.output, " (", format == "spz" ? msg("spz-v", args.spzVersion) : format, ")"));
}

const CommandRegistrar reg(21, [](CLI::App& app) {
    auto args = std::make_shared<ConvertArgs>();
    CLI::App* sub = app.add_subcommand(
        "convert", "Convert a Gaussian model between formats: reads any model " + kModelFormats +
                       "; writes .ply, .compressed.ply, .splat, .spz, .glb, .vdb (--points), .sog (bundle) or meta.json "
                       "(SOG folder) by the output's name");
    sub->add_option("input", args->input, "Input Gaussian file " + kModelFormats)->required();
    sub->add_option("output", args->output, "Output path; its extension picks the format (written atomically)")
        ->required();
    sub->add_flag("--points", args->points, "Write a .vdb output as an OpenVDB point grid (Houdini GSplat attributes)");
    sub->add_option("--spz-version", args->spzVersion, "Version of a .spz output: 3 (gzip, default) or 4 (zstd)")
        ->check(CLI::IsMember({3, 4}));
    sub->add_option("--sog-seed", args->sog.seed, "SOG output: seed of the SH palette's k-means (same seed, same bytes)")
        ->check(kSeedRange)
        ->capture_default_str();
    sub->add_option("--sog-iterations", args->sog.iterations, "SOG output: k-means iterations of the SH palette")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    sub->add_option("--sog-palette", args->sog.maxPalette,
                    "SOG output: most SH palette entries; the palette is splat-transform's size, the largest power of two "
                    "<= the Gaussians, up to this (past 4096 entries a Gaussian searches the groups of entries nearest it)")
        ->check(CLI::Range(1, 65536))
        ->capture_default_str();
    addDropInvalidFlag(sub, args->dropInvalid);
    sub->add_flag("--drop-outliers", args->dropOutliers,
                  "Drop the outliers `info` warns of: Gaussians whose centre lies outside the box of the central 98% "
                  "of centres (per axis) by more than that box's largest side (far floaters, stray points), and those "
                  "with a standard deviation over half that side (a sky, a blur); says how many");
    sub->callback([args, sub] {
        args->spzFlagGiven = sub->count("--spz-version") > 0;
        args->sogFlagGiven = sub->count("--sog-seed") + sub->count("--sog-iterations") + sub->count("--sog-palette") > 0;
        convert(*args);
    });
});

} // namespace
} // namespace splatwarp::cli
