/// `splatwarp deform IN --spec SPEC.json -o OUTDIR`: Stage I (embedded deformation) and Stage II
/// (fit to the warped radiance field) -> baseline.ply, deformed.ply, report.json [, field.vdb, compare.png].
#include <cstdio>

#include "DeformArgs.h"
#include "ReadArgs.h"
#include "core/Error.h"

namespace splatwarp::cli {
namespace {

const CommandRegistrar reg(30, [](CLI::App& app) {
    auto args = std::make_shared<DeformArgs>();
    DeformJobOptions& job = args->job;
    CLI::App* sub = app.add_subcommand(
        "deform", "Deform a 3DGS model with a deformation spec: Stage I (embedded deformation) then Stage II "
                  "(fit the Gaussians to the warped radiance field)");
    sub->add_option("input", job.input, "Input model " + kModelFormats)->required();
    sub->add_option("--spec", job.specPath, "Deformation spec JSON (see samples/specs/README.md)")->required();
    sub->add_option("-o,--output", job.outDir, "Output directory (created): baseline.ply, deformed.ply, report.json; all appear together at the end, or none")->required();
    addDeformOptions(sub, *args);
    // About eight flags a user touches (the table's user level); the other ~35 are listed by --help-all.
    splitHelpLevels(sub, userFlags({"--spec", "-o"}));
    sub->callback([args] {
        const DeformJobOptions job = deformJobOptions(*args);
        if (job.render && job.stage1Only) throw UsageError("--render needs Stage II (drop --stage1-only)");
        const FrameReport report = runDeformJob(job);
        // A short summary on stdout (progress lines go to stderr).
        std::printf("outputs:");
        for (const auto& [name, path] : report.outputs) std::printf(" %s", path.c_str());
        std::printf(" %s/report.json\n", job.outDir.c_str());
        if (report.stage1Errors && report.stage2 && report.stage2->errors) {
            const FieldErrorReport& e1 = report.stage1Errors->judge.field;
            const FieldErrorReport& e2 = report.stage2->errors->judge.field;
            std::printf("judged field error (opacity, color): Stage I %.6g, %.6g -> Stage II %.6g, %.6g\n", e1.opacity,
                        e1.color, e2.opacity, e2.color);
        }
    });
});

} // namespace
} // namespace splatwarp::cli
