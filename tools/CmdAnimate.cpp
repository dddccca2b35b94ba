/// `splatwarp animate IN --spec ANIM.json -o DIR`: a keyframed deformation, one `deform` per frame
/// on a rest side computed once; shards, resume and a manifest (job/AnimateJob.h).
#include <cstdio>

#include "job/AnimateJob.h"
#include "DeformArgs.h"
#include "ReadArgs.h"
#include "job/WarmStart.h"
#include "core/Error.h"

namespace splatwarp::cli {
namespace {

struct AnimateArgs {
    DeformArgs deform;
    std::string frames, shard, merge;
    int shardCount = 0;
    bool zip = false, specsOnly = false, warmStart = false;
};

/// "A-B" or "A" into first/last.
void parseFrames(const std::string& text, AnimateJobOptions& job)
{
    const std::size_t dash = text.find('-');
    try {
        std::size_t used = 0;
        job.first = std::stoi(text.substr(0, dash), &used);
        if (used != (dash == std::string::npos ? text.size() : dash)) throw std::invalid_argument("trailing");
        job.last = dash == std::string::npos ? job.first : std::stoi(text.substr(dash + 1), &used);
        if (dash != std::string::npos && used != text.size() - dash - 1) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
        throw UsageError(msg("--frames must be A-B or A (frame numbers, e.g. 0-23), got \"", text, "\""));
    }
    if (job.first < 0 || job.last < job.first) throw UsageError(msg("--frames ", text, ": need 0 <= A <= B"));
}

void printSummary(const char* what, const nlohmann::json& merged)
{
    std::printf("%s: %zu entries, missing %s, failed %s\n", what, merged["entries"].size(), merged["missing"].dump().c_str(),
                merged["failed"].dump().c_str());
}

const CommandRegistrar reg(35, [](CLI::App& app) {
    auto args = std::make_shared<AnimateArgs>();
    DeformJobOptions& job = args->deform.job;
    CLI::App* sub = app.add_subcommand(
        "animate", "Animate a 3DGS model with a keyframed deformation spec: one deform per frame on a rest side "
                   "computed once -> DIR/frames/deformed.0000.ply ..., DIR/manifest.json");
    sub->add_option("input", job.input, "Input model " + kModelFormats);
    sub->add_option("--spec", job.specPath, "Keyframed spec JSON (\"frames\", per handle \"keys\"; see samples/specs/README.md)");
    sub->add_option("-o,--output", job.outDir, "Output directory (created): frames/, vdb/, preview/, manifest.json");
    sub->add_option("--frames", args->frames, "Only frames A-B (inclusive), e.g. 0-11");
    sub->add_option("--shard", args->shard, "Take frames f with f mod N = I (I/N; with --warm-start the I-th of N contiguous ranges of frame pairs); "
                                     "default from SLURM_ARRAY_TASK_ID/COUNT or JOB_COMPLETION_INDEX");
    sub->add_option("--shard-count", args->shardCount, "Shard count N with JOB_COMPLETION_INDEX (Kubernetes Indexed Job completions)")
        ->check(positive());
    sub->add_option("--merge", args->merge, "Join DIR/manifest.shard-*.json into DIR/manifest.json and list missing or failed frames");
    sub->add_flag("--specs-only", args->specsOnly,
                  "Only write each frame's plain spec to DIR/specs/spec.0000.json ... (deform --spec with one reproduces that frame)");
    addDeformOptions(sub, args->deform);
    sub->add_flag("--warm-start", args->warmStart,
                  msg("Frames in pairs (2k, 2k+1): Stage II of each odd frame starts from the even frame's fit carried onto "
                      "its Stage I model (even frames stay equal to deform), unless that start's training energy is over ",
                      kWarmEnergyLimit, "x the even frame's fit: then it starts cold too (the manifest says which start each "
                      "frame used). Less CPU per frame, measured in docs/lab/animation-study.md. Shards then take contiguous "
                      "ranges of pairs; a frame whose predecessor was not computed in this run recomputes it (not written)"))
        ->excludes(sub->get_option("--stage1-only"));
    sub->add_flag("--zip", args->zip, "Also write sequence.zip of the frame PLYs (by a whole run, or by --merge)");
    splitHelpLevels(sub, {"--spec", "-o", "--frames", "--shard", "--merge", "--vdb", "--render", "--zip"});
    sub->callback([args, sub] {
        if (!args->merge.empty()) {
            const nlohmann::json merged = mergeAnimate(args->merge, args->zip);
            printSummary("merged", merged);
            if (!merged["missing"].empty() || !merged["failed"].empty())
                throw InputError(msg(args->merge, ": frames missing ", merged["missing"].dump(), ", failed ", merged["failed"].dump(),
                                     mergeFailures(merged)));
            return;
        }
        AnimateJobOptions options;
        options.deform = deformJobOptions(args->deform);
        if ((options.deform.input.empty() && !args->specsOnly) || options.deform.specPath.empty() || options.deform.outDir.empty())
            throw UsageError("animate needs INPUT, --spec and -o (or --merge DIR)");
        if (!args->frames.empty()) parseFrames(args->frames, options);
        if (args->specsOnly) {
            std::printf("wrote %d frame specs to %s/specs/\n", writeFrameSpecs(options), options.deform.outDir.c_str());
            return;
        }
        options.shard = resolveShard(args->shard, args->shardCount);
        options.zip = args->zip;
        options.warmStart = args->warmStart;
        const SequenceResult r = runAnimateJob(options);
        std::printf("frames: %d done, %d resumed, %d failed (shard %d/%d from %s); manifest %s\n", r.done, r.resumed,
                    r.failed, options.shard.index, options.shard.count, options.shard.source.c_str(), r.manifest.c_str());
        if (r.failed > 0) throw InputError(msg(r.failed, " frame(s) failed; their messages are in ", r.manifest));
    });
});

} // namespace
} // namespace splatwarp::cli
