/// The module's jobs: deform (the session API), to_vdb, from_vdb, render and eval, each the
/// library calls of its CLI command, with the GIL released while they run.
#include <atomic>
#include <optional>

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include "DeformArgs.h"
#include "GridArgs.h"
#include "PyCommon.h"
#include "core/AtomicFile.h"
#include "core/Camera.h"
#include "core/Error.h"
#include "core/Memory.h"
#include "core/RunControl.h"
#include "deform/DeformSpec.h"
#include "deform/WarpDevice.h"
#include "image/ImageIO.h"
#include "io/CameraFiles.h"
#include "job/DeformSession.h"
#include "job/FromVdb.h"
#include "job/Judge.h"
#include "render/RenderDevice.h"
#include "vdb/VdbExport.h"

namespace py = pybind11;

namespace splatwarp::python {
namespace {

/// What deform() returns.
struct DeformResult {
    py::object stage1, result, report;
};

/// report.json's JSON as Python objects (made at the edge: the library keeps nlohmann::json).
py::object toPython(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

/// A spec path (read as deform reads it) or a dict (the same JSON); `path` receives the path or "".
DeformSpec specOf(const py::handle& spec, std::string& path)
{
    if (py::isinstance<py::dict>(spec)) {
        path.clear();
        return parseDeformSpec(py::module_::import("json").attr("dumps")(spec).cast<std::string>(), "spec");
    }
    path = pathOf(spec);
    return loadDeformSpec(path);
}

/// deform's keyword settings through deform's own flags (and the recipe they name), as the CLI.
DeformJobOptions deformOptions(const py::kwargs& settings)
{
    cli::DeformArgs args;
    CLI::App app;
    CLI::App* sub = app.add_subcommand("deform");
    cli::addDeformOptions(sub, args);
    parseSettings(app, sub, "deform", settings);
    DeformJobOptions job = cli::deformJobOptions(args);
    if (job.render && job.stage1Only) throw UsageError("--render needs Stage II (drop --stage1-only)");
    return job;
}

/// Ctrl-C during Stage II: each iteration's progress report looks at Python's signals and cancels.
struct Interrupts {
    std::atomic<bool> cancel{false};
    RunControl control()
    {
        RunControl c;
        c.cancel = &cancel;
        c.onProgress = [this](const std::string&, int, int) {
            py::gil_scoped_acquire gil;
            if (PyErr_CheckSignals() != 0) cancel = true; // KeyboardInterrupt stays set for the caller
        };
        return c;
    }
};

DeformResult deform(const py::object& model, const py::object& spec, const py::object& output, const py::kwargs& settings)
{
    const LibraryTurn turn;
    DeformJobOptions options = deformOptions(settings);
    const DeformSpec parsed = specOf(spec, options.specPath);
    std::optional<GaussianCloud> cloud;
    if (py::isinstance<GaussianCloud>(model)) {
        cloud = model.cast<const GaussianCloud&>();
        checkModelInMemory("(model)", *cloud);
    }
    options.input = cloud ? "(model)" : pathOf(model);
    const std::string out = output.is_none() ? std::string() : pathOf(output);
    GaussianCloud stage1;
    std::optional<GaussianCloud> fitted;
    FrameReport report;
    Interrupts interrupts;
    try {
        py::gil_scoped_release release;
        auto session = cloud ? std::make_unique<DeformSession>(options, parsed, std::move(*cloud))
                             : std::make_unique<DeformSession>(options, parsed);
        stage1 = session->pose(parsed).deformed;
        if (!options.stage1Only) fitted = session->refine(interrupts.control());
        report = out.empty() ? session->report() : session->write(out);
    } catch (const Cancelled&) {
        if (PyErr_Occurred()) throw py::error_already_set();
        throw;
    }
    return {py::cast(std::move(stage1)), fitted ? py::cast(std::move(*fitted)) : py::none(), toPython(report.toJson())};
}

void toVdb(const py::object& model, const py::object& path, const py::object& spec, bool shGrids, bool half,
           const std::string& device, const py::kwargs& gridSettings)
{
    const LibraryTurn turn;
    SampleGridOptions grid;
    CLI::App app;
    CLI::App* sub = app.add_subcommand("to-vdb");
    cli::addGridOptions(sub, grid);
    parseSettings(app, sub, "to_vdb", gridSettings);
    grid.device = resolveDevice(parseDevice(device));
    VdbExportOptions vdb;
    vdb.shGrids = shGrids;
    vdb.half = half;
    std::optional<DeformSpec> parsed;
    if (!spec.is_none()) parsed = specOf(spec, vdb.spec);
    const GaussianCloud cloud = modelOrPath(model, vdb.source);
    const std::string out = pathOf(path);
    py::gil_scoped_release release;
    OutputSet outputs({vdb.source, vdb.spec});
    outputs.checkTarget(out);
    SampleGrid samples = runStage("sample grid", [&] { return SampleGrid(cloud, grid); });
    if (parsed) {
        warpSamplesOn(samples.samples(), solveDeformation(cloud, *parsed), {grid.device});
        if (vdb.spec.empty()) vdb.spec = "spec";
        vdb.stretch = true;
    }
    runStage("VDB export", [&] { writeSampleGridVdb(out, samples, vdb); });
    outputs.commit();
}

py::object fromVdb(const py::object& path, const FromVdbOptions& defaults, std::size_t gaussians, int iterations, int rounds,
                   bool fit, const std::string& meaning, const std::string& grid, const std::string& colorGrid,
                   const std::string& device, bool withReport)
{
    const LibraryTurn turn;
    // from-vdb's ranges (tools/CmdFromVdb.cpp)
    if (gaussians > std::size_t(1e9)) throw py::value_error("from_vdb(): gaussians must be 0 (one per 8 active voxels) to 1e9");
    if (iterations < 0) throw py::value_error("from_vdb(): iterations must not be negative");
    if (rounds < 1 || rounds > 100) throw py::value_error("from_vdb(): rounds must be 1 to 100");
    FromVdbOptions job = defaults;
    job.gaussians = gaussians;
    job.fitting.iterations = iterations;
    job.fitting.rounds = rounds;
    job.fit = fit;
    job.meaning = parseVolumeMeaning(meaning);
    job.fitting.stage2.device = resolveDevice(parseDevice(device));
    VolumeReadOptions read;
    read.grid = grid;
    read.colorGrid = colorGrid;
    const std::string input = pathOf(path);
    FromVdbResult result;
    Interrupts interrupts;
    try {
        py::gil_scoped_release release;
        const RunControl control = interrupts.control();
        const RunControlScope scope(control);
        result = fromVdb(readVolume(input, read), job);
    } catch (const Cancelled&) {
        if (PyErr_Occurred()) throw py::error_already_set();
        throw;
    }
    py::object model = py::cast(std::move(result.splats));
    return withReport ? py::object(py::make_tuple(model, toPython(result.report))) : model;
}

/// A width or height: a whole number (not a bool) from 1 to kMaxImageSide.
int imageSide(const py::object& side)
{
    const std::string range = msg("render(): width and height must be whole numbers from 1 to ", kMaxImageSide);
    if (!py::isinstance<py::int_>(side) || py::isinstance<py::bool_>(side)) throw py::type_error(range);
    long long v = 0;
    try {
        v = side.cast<long long>();
    } catch (const py::cast_error&) { // beyond 64 bits
        throw py::value_error(range);
    }
    if (v < 1 || v > kMaxImageSide) throw py::value_error(range);
    return int(v);
}

/// The cameras `render` uses: a camera file's (its size, or width x height), else an orbit.
std::vector<Camera> renderCameras(const GaussianCloud& cloud, const py::object& cameraFile, OrbitOptions orbit,
                                  const py::object& width, const py::object& height)
{
    if (width.is_none() != height.is_none()) throw py::value_error("render(): give width and height together");
    const int w = width.is_none() ? 0 : imageSide(width), h = height.is_none() ? 0 : imageSide(height);
    if (cameraFile.is_none()) {
        if (w > 0) {
            orbit.width = w;
            orbit.height = h;
        }
        return orbitCameras(cloud, orbit);
    }
    CameraFileOptions fileOptions;
    fileOptions.width = w;
    fileOptions.height = h;
    std::vector<Camera> cameras = readCameraFile(pathOf(cameraFile), fileOptions);
    if (w > 0)
        for (Camera& c : cameras) c = c.resized(w, h);
    return cameras;
}

py::array render(const py::object& model, const py::object& width, const py::object& height, const py::object& camera,
                 const OrbitOptions& orbit, std::size_t view, const std::array<float, 3>& background,
                 const std::string& device, const std::string& dtype)
{
    const LibraryTurn turn;
    if (dtype != "uint8" && dtype != "float32") throw py::value_error("render(): dtype must be 'uint8' or 'float32'");
    RenderOptions options;
    for (int c = 0; c < 3; ++c) {
        if (!(background[c] >= 0.0f && background[c] <= 1.0f))
            throw py::value_error("render(): background components must lie in [0, 1]");
        options.background[c] = background[c];
    }
    options.device = resolveDevice(parseDevice(device));
    std::string name;
    const GaussianCloud cloud = modelOrPath(model, name);
    const std::vector<Camera> cameras = renderCameras(cloud, camera, orbit, width, height);
    if (view >= cameras.size()) throw py::index_error(msg("render(): view ", view, " of ", cameras.size(), " cameras"));
    Image image;
    {
        py::gil_scoped_release release;
        image = renderGaussiansOn(cloud, cameras[view], options);
    }
    const std::vector<py::ssize_t> shape{image.height, image.width, image.channels};
    if (dtype == "float32") return py::array_t<float>(shape, image.pixels.data());
    const std::vector<std::uint8_t> bytes = pngBytes("render", image);
    return py::array_t<std::uint8_t>(std::vector<py::ssize_t>{image.height, image.width, 3}, bytes.data());
}

py::object evaluate(const py::object& restModel, const py::object& deformedModel, const py::object& spec,
                    const HeldOutOptions& defaults, std::size_t points, std::uint32_t seed, const std::string& device)
{
    const LibraryTurn turn;
    std::string restName, deformedName, specPath;
    const GaussianCloud rest = modelOrPath(restModel, restName, "(rest model)");
    const GaussianCloud deformed = modelOrPath(deformedModel, deformedName, "(deformed model)");
    if (deformed.shDegree != rest.shDegree)
        throw InputError(msg(deformedName, ": SH degree ", deformed.shDegree, " differs from the rest model's ", rest.shDegree));
    const DeformSpec parsed = specOf(spec, specPath);
    HeldOutOptions heldOut = defaults;
    heldOut.points = points;
    heldOut.seed = seed;
    heldOut.device = resolveDevice(parseDevice(device));
    if (points == 0) throw py::value_error("eval(): points must be positive");
    checkEvalPointMemory(points, rest.shStride(), true, 0, defaultMemoryBudget(), "points");
    JudgeReport report;
    {
        py::gil_scoped_release release;
        const Judge judge(rest, prepareJudgeRest(rest, heldOut), solveDeformation(rest, parsed));
        report = judge.judge(deformed);
    }
    return toPython(judgeJson(report));
}

void bindDeform(py::module_& m)
{
    py::class_<DeformResult>(m, "DeformResult", "What deform() returns.")
        .def_readonly("stage1", &DeformResult::stage1, "Stage I's model (what deform writes as baseline.ply).")
        .def_readonly("result", &DeformResult::result, "Stage II's model (deformed.ply); None with stage1_only.")
        .def_readonly("report", &DeformResult::report, "report.json as a dict (with output: the one written).");
    m.def("deform", &deform, py::arg("model"), py::arg("spec"), py::kw_only(), py::arg("output") = py::none(),
          "deform(model, spec, *, output=None, **settings) -> DeformResult\n\n"
          "Deform a Model (or a model file) with a spec (a path, or a dict of the same JSON) as `splatwarp deform`:\n"
          "Stage I, then Stage II unless stage1_only. Each keyword setting is deform's flag of that name\n"
          "(recipe='paper', iterations=50, cells=32, seed=3, device='cpu', stage1_only=True, no_eval=True, ...;\n"
          "see `splatwarp deform --help-all`), checked as the CLI checks it; an unknown one is a TypeError.\n"
          "With output=DIR it also writes what deform -o DIR writes (vdb=True, render=True add the extras).\n"
          "Ctrl-C stops Stage II within one iteration. Calls from several threads take turns.");
}

void bindVolumes(py::module_& m)
{
    m.def("to_vdb", &toVdb, py::arg("model"), py::arg("path"), py::kw_only(), py::arg("spec") = py::none(),
          py::arg("sh_grids") = false, py::arg("half") = false, py::arg("device") = "auto",
          "to_vdb(model, path, *, spec=None, sh_grids=False, half=False, device='auto', **grid)\n\n"
          "Sample a model's radiance field into an OpenVDB file as `splatwarp to-vdb`; grid settings are its flags\n"
          "(cells, cell_size, samples_per_cell, cutoff, max_memory). A spec warps the samples and adds `stretch`.");
    const FromVdbOptions d = defaultFromVdbOptions();
    m.def(
        "from_vdb",
        [d](const py::object& path, std::size_t gaussians, int iterations, int rounds, bool fit, const std::string& meaning,
            const std::string& grid, const std::string& colorGrid, const std::string& device, bool report) {
            return fromVdb(path, d, gaussians, iterations, rounds, fit, meaning, grid, colorGrid, device, report);
        },
        py::arg("path"), py::kw_only(), py::arg("gaussians") = d.gaussians, py::arg("iterations") = d.fitting.iterations,
        py::arg("rounds") = d.fitting.rounds, py::arg("fit") = d.fit, py::arg("meaning") = "auto", py::arg("grid") = "",
        py::arg("color_grid") = "", py::arg("device") = "auto", py::arg("report") = false,
        "Fit Gaussians to an OpenVDB fog volume as `splatwarp from-vdb` (meaning: auto, field or extinction, its --as;\n"
        "fit=False is --no-fit). Returns the Model, or (Model, report dict) with report=True.");
}

void bindRenderEval(py::module_& m)
{
    const OrbitOptions o;
    m.def(
        "render",
        [](const py::object& model, const py::object& width, const py::object& height, const py::object& camera,
           int orbit, std::size_t view, double elevation, double fov, double distance, const std::string& up,
           const std::array<float, 3>& background, const std::string& device, const std::string& dtype) {
            OrbitOptions options; // its ranges are checked where the cameras are placed (orbitCameras())
            options.views = orbit;
            options.elevationDeg = elevation;
            options.fovDeg = fov;
            options.distanceFactor = distance;
            options.up = up;
            return render(model, width, height, camera, options, view, background, device, dtype);
        },
        py::arg("model"), py::arg("width") = py::none(), py::arg("height") = py::none(), py::kw_only(),
        py::arg("camera") = py::none(), py::arg("orbit") = 1, py::arg("view") = 0, py::arg("elevation") = o.elevationDeg,
        py::arg("fov") = o.fovDeg, py::arg("distance") = o.distanceFactor, py::arg("up") = o.up,
        py::arg("background") = std::array<float, 3>{0.0f, 0.0f, 0.0f}, py::arg("device") = "auto", py::arg("dtype") = "uint8",
        "Render view `view` of `orbit` orbit cameras (or of a camera file) as `splatwarp render`: dtype 'uint8' gives\n"
        "(H, W, 3) with the PNG's values, 'float32' (H, W, 4) display values RGBA.");
    const HeldOutOptions h;
    m.def(
        "eval",
        [h](const py::object& rest, const py::object& deformed, const py::object& spec, std::size_t points,
            std::uint32_t seed, const std::string& device) { return evaluate(rest, deformed, spec, h, points, seed, device); },
        py::arg("rest"), py::arg("deformed"), py::arg("spec"), py::kw_only(), py::arg("points") = h.points,
        py::arg("seed") = h.seed, py::arg("device") = "auto",
        "The fixed judge as `splatwarp eval --json`: a dict of the field error of `deformed` against `rest` pushed\n"
        "through `spec` (opacity, color, points, inside, outside; image_psnr for a rigid spec).");
}

} // namespace

void bindJobs(py::module_& m)
{
    bindDeform(m);
    bindVolumes(m);
    bindRenderEval(m);
}

} // namespace splatwarp::python
