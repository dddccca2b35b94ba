#include "DeformPipeline.h"

#include <filesystem>

#include "deform/SampleWarp.h"
#include "VdbExport.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "deform/DeformReport.h"
#include "deform/StageOneDevice.h"
#include "deform/WarpDevice.h"
#include "image/ImageIO.h"
#include "io/GaussianIO.h"
#include "render/Camera.h"
#include "render/ComparisonSheet.h"
#include "stage2/StageTwoDevice.h"

namespace splatwarp {

namespace {

std::string outPath(const DeformJobOptions& o, const char* name)
{
    return (std::filesystem::path(o.outDir) / name).string();
}

nlohmann::json stageTwoJson(const StageTwoReport& r, const SampleGrid& grid, const StageTwoOptions& o)
{
    nlohmann::json energies = nlohmann::json::array();
    for (const StageTwoEnergy& e : r.energies)
        energies.push_back({{"iteration", e.iteration}, {"total", e.total}, {"color", e.color}, {"opacity", e.opacity},
                            {"boundary", e.boundary}});
    std::uint64_t pairs = 0;
    for (std::uint64_t p : r.pairsPerIteration) pairs += p;
    const double pairsPerIteration = r.pairsPerIteration.empty() ? 0.0 : double(pairs) / r.pairsPerIteration.size();
    return {{"energies", energies},
            {"movingGaussians", r.movingGaussians},
            {"activeCells", grid.stats().cells},
            {"skippedCells", grid.stats().skippedCells},
            {"samples", grid.stats().samples},
            {"samplesUsed", r.samplesUsed},
            {"pairsPerIteration", pairsPerIteration},
            {"pairsPerSecond", r.msForward + r.msBackward > 0 ? pairs / ((r.msForward + r.msBackward) / 1000.0) : 0.0},
            {"coverageRebuilds", r.coverageRebuilds},
            {"bestIteration", r.bestIteration},
            {"bestEnergy", r.bestEnergy},
            {"device", r.device},
            {"gpuPeakBytes", r.gpuPeakBytes},
            {"sceneExtent", r.sceneExtent},
            {"parameters",
             {{"iterations", o.iterations}, {"lambdaOpacity", o.lambdaOpacity}, {"boundaryWeight", o.boundaryWeight},
              {"lowPassFilter", o.lowPassFilter}, {"lambdaLpf", o.lambdaLpf}, {"rebuildEvery", o.rebuildEvery},
              {"cutoff", o.cutoff}, {"keepBest", o.keepBest}}},
            {"timingsMs",
             {{"setup", r.msSetup}, {"coverage", r.msCoverage}, {"forward", r.msForward}, {"backward", r.msBackward},
              {"update", r.msUpdate}, {"total", r.msTotal}}}};
}

/// Cameras that frame both the rest and the deformed shape.
std::vector<Camera> comparisonCameras(const GaussianCloud& rest, const GaussianCloud& deformed, const DeformJobOptions& o)
{
    GaussianCloud both = rest;
    for (std::size_t i = 0; i < deformed.size(); ++i) both.append(deformed, i);
    OrbitOptions orbit;
    orbit.views = o.renderViews;
    orbit.width = orbit.height = o.renderSize;
    return orbitCameras(both, orbit);
}

} // namespace

nlohmann::json runDeformJob(const DeformJobOptions& o)
{
    Stopwatch total, clock;
    resolveDevice(o.device); // fail before any work when the device cannot run
    DeformSpec spec = loadDeformSpec(o.specPath);
    if (o.nodes) spec.graph.nodes = *o.nodes;
    if (o.k) spec.graph.k = *o.k;
    if (o.seed) spec.graph.seed = *o.seed;
    ReadReport readReport;
    const GaussianCloud rest = readGaussians(o.input, ReadOptions{}, &readReport);
    const double readMs = clock.ms();
    progress(msg("read ", rest.size(), " Gaussians (SH degree ", rest.shDegree, ") from ", o.input));

    std::error_code ec;
    std::filesystem::create_directories(o.outDir, ec);
    if (ec) throw IoError(msg(o.outDir, ": cannot create output directory: ", ec.message()));

    // Stage I.
    const Deformation deformation = solveDeformation(rest, spec, o.ed);
    const StageOneResult stage1 = runStageOneOn(o.device, rest, deformation, o.stage1);
    nlohmann::json report = stageOneReportJson(deformation, stage1, spec.graph, o.ed);
    report["input"] = {{"path", o.input}, {"format", readReport.format}, {"gaussians", rest.size()},
                       {"shDegree", rest.shDegree}};
    report["spec"] = o.specPath;
    report["timingsMs"]["read"] = readMs;
    const std::string baseline = outPath(o, "baseline.ply");
    clock.reset();
    writePly(baseline, stage1.deformed);
    double writeMs = clock.ms();
    report["outputs"]["baseline"] = baseline;

    if (!o.stage1Only) {
        // The rest field sampled into sparse cells, then warped by the same deformation.
        clock.reset();
        SampleGrid grid(rest, withDevice(o.grid, o.device));
        report["timingsMs"]["sampleGrid"] = clock.ms();
        clock.reset();
        const char* warpDevice = warpSamplesOn(o.device, grid.samples(), deformation, o.grid.threaded);
        report["timingsMs"]["warpSamples"] = clock.ms();
        report["warpDevice"] = warpDevice;
        progress(msg("warped ", grid.stats().samples, " samples in ", int(clock.ms()), " ms on ", warpDevice));

        std::optional<HeldOutPoints> heldOut;
        std::optional<FieldErrorTarget> heldOutRest; // the rest side, computed once for every evaluation
        if (o.evaluate || o.evalEvery > 0) {
            clock.reset();
            HeldOutOptions heldOutOptions = o.heldOut;
            heldOutOptions.device = o.device;
            heldOut = makeHeldOutPoints(grid, deformation, heldOutOptions);
            heldOutRest = heldOutTarget(rest, *heldOut, o.device);
            const FieldErrorReport e1 = evaluateHeldOut(*heldOutRest, stage1.deformed, *heldOut, o.device);
            report["stage1"]["field_error"] = fieldErrorJson(e1);
            report["timingsMs"]["evaluate"] = clock.ms();
            progress(msg("Stage I held-out field error: opacity ", e1.opacity, ", color ", e1.color));
        }

        // Stage II: fit the moving Gaussians to the warped field.
        GaussianCloud fitted = stage1.deformed;
        nlohmann::json curve = nlohmann::json::array();
        auto onEval = [&](int iteration, const GaussianCloud& current) {
            const FieldErrorReport e = evaluateHeldOut(*heldOutRest, current, *heldOut, o.device);
            nlohmann::json j = fieldErrorJson(e);
            j["iteration"] = iteration;
            curve.push_back(j);
            progress(msg("Stage II iteration ", iteration, ": held-out opacity error ", e.opacity));
        };
        progress(msg("Stage II: ", o.stage2.iterations, " iterations on ", stage1.movingCount, " moving Gaussians"));
        const StageTwoReport r2 = runStageTwo(o.device, fitted, grid.samples(), stage1.moving, grid.gaussianCell(), o.stage2,
                                                   o.evalEvery > 0 ? std::function<void(int, const GaussianCloud&)>(onEval)
                                                                   : std::function<void(int, const GaussianCloud&)>(),
                                                   o.evalEvery);
        report["stage2"] = stageTwoJson(r2, grid, o.stage2);
        report["timingsMs"]["stage2"] = r2.msTotal;
        if (o.evalEvery > 0) report["stage2"]["eval_curve"] = curve;
        if (heldOut) {
            const FieldErrorReport e2 = evaluateHeldOut(*heldOutRest, fitted, *heldOut, o.device);
            report["stage2"]["field_error"] = fieldErrorJson(e2);
            progress(msg("Stage II held-out field error: opacity ", e2.opacity, ", color ", e2.color));
        }
        const std::string deformed = outPath(o, "deformed.ply");
        clock.reset();
        writePly(deformed, fitted);
        writeMs += clock.ms();
        report["outputs"]["deformed"] = deformed;

        if (o.writeVdb) {
            clock.reset();
            SampleGridOptions go = withDevice(o.grid, o.device);
            const SampleGrid fieldGrid(fitted, go);
            VdbExportOptions vo;
            vo.source = deformed;
            vo.threaded = o.grid.threaded;
            const std::string vdb = outPath(o, "field.vdb");
            writeSampleGridVdb(vdb, fieldGrid, vo);
            report["outputs"]["field"] = vdb;
            report["timingsMs"]["vdb"] = clock.ms();
        }
        if (o.render) {
            clock.reset();
            ComparisonSheetOptions sheetOptions;
            sheetOptions.device = o.device;
            const Image sheet = renderComparisonSheet({&rest, &stage1.deformed, &fitted}, {"rest", "stage I", "stage II"},
                                                      comparisonCameras(rest, fitted, o), sheetOptions);
            const std::string png = outPath(o, "compare.png");
            writePng(png, sheet);
            report["outputs"]["compare"] = png;
            report["timingsMs"]["render"] = clock.ms();
        }
    }
    report["timingsMs"]["write"] = writeMs;
    report["timingsMs"]["total"] = total.ms();
    const std::string reportPath = outPath(o, "report.json");
    writeFileAtomic(reportPath, report.dump(2) + "\n");
    progress(msg("wrote ", o.outDir, "/{", o.stage1Only ? "baseline.ply" : "baseline.ply, deformed.ply", ", report.json}"));
    return report;
}

} // namespace splatwarp
