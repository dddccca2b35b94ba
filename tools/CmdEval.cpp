/// `splatwarp eval --rest REST.ply --deformed DEF.ply --spec SPEC.json`: held-out field fidelity of
/// any deformed model against the rest model pushed through the spec's deformation.
#include <cstdio>

#include "Command.h"
#include "GridArgs.h"
#include "HeldOutEval.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "deform/DeformSpec.h"
#include "io/GaussianIO.h"

namespace splatwarp::cli {
namespace {

struct EvalArgs {
    std::string rest, deformed, spec;
    bool json = false;
    std::string device = "auto";
    SampleGridOptions grid;
    HeldOutOptions heldOut;
};

const CommandRegistrar reg(35, [](CLI::App& app) {
    auto a = std::make_shared<EvalArgs>();
    CLI::App* sub = app.add_subcommand(
        "eval", "Field fidelity of a deformed model: relative L1 error of opacity and SH features at held-out points "
                "of the rest field pushed through the spec's deformation (inside the object and outside it)");
    sub->add_option("--rest", a->rest, "Rest (undeformed) model")->required();
    sub->add_option("--deformed", a->deformed, "Deformed model to judge (e.g. baseline.ply or deformed.ply)")
        ->required()
        ;
    sub->add_option("--spec", a->spec, "The deformation spec that produced it")->required();
    sub->add_option("--points", a->heldOut.points, "Held-out points")->capture_default_str()->check(CLI::PositiveNumber);
    sub->add_option("--seed", a->heldOut.seed, "Seed of the held-out points")->capture_default_str();
    addGridOptions(sub, a->grid);
    sub->add_flag("--json", a->json, "Print JSON (keys opacity, color, points, inside, outside)");
    addDeviceOption(sub, a->device, "the rest targets, the point warping and the feature evaluations run (the grid's topology stays on the CPU)");
    sub->callback([a] {
        const Device device = parseDevice(a->device);
        const GaussianCloud rest = readGaussians(a->rest);
        const GaussianCloud deformed = readGaussians(a->deformed);
        if (deformed.shDegree != rest.shDegree)
            throw InputError(msg(a->deformed, ": SH degree ", deformed.shDegree, " differs from the rest model's ", rest.shDegree));
        const Deformation deformation = solveDeformation(rest, loadDeformSpec(a->spec));
        const SampleGrid grid(rest, withDevice(a->grid, device));
        HeldOutOptions heldOut = a->heldOut;
        heldOut.device = device;
        const HeldOutPoints points = makeHeldOutPoints(grid, deformation, heldOut);
        const FieldErrorReport r = evaluateHeldOut(rest, deformed, points, device);
        if (a->json) {
            std::printf("%s\n", fieldErrorJson(r).dump(2).c_str());
            return;
        }
        std::printf("held-out points: %zu (%zu inside, %zu outside)\n", r.points, r.insidePoints, r.outsidePoints);
        std::printf("opacity error:   %.6g (inside %.6g, outside %.6g)\n", r.opacity, r.opacityInside, r.opacityOutside);
        std::printf("color error:     %.6g (inside %.6g, outside %.6g)\n", r.color, r.colorInside, r.colorOutside);
    });
});

} // namespace
} // namespace splatwarp::cli
