/// The `splatwarp` Python module (pybind11): models as numpy views onto the C++ arrays, and the
/// library's read, write, deform, to-vdb, from-vdb, render and eval. Keyword settings of deform
/// and to_vdb are the CLI's flags, parsed by the CLI's own definitions (tools/DeformArgs.h,
/// tools/GridArgs.h), so a setting means and checks exactly what its flag does.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "PyCommon.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "io/GaussianIO.h"
#include "vdb/VdbPoints.h"
#ifdef SPLATWARP_WITH_CUDA
#include "kernels/CudaBackends.h"
#endif

namespace py = pybind11;

namespace splatwarp::python {
namespace {

/// A float32 numpy view of `data` owned by the Model `owner` (kept alive as the array's base).
py::array floatView(py::handle owner, float* data, std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides)
{
    for (py::ssize_t& s : strides) s *= py::ssize_t(sizeof(float));
    return py::array(py::dtype::of<float>(), std::move(shape), std::move(strides), data, owner);
}

GaussianCloud& cloudOf(py::handle self) { return self.cast<GaussianCloud&>(); }

/// An (N, ...) float32 C-contiguous array; a wrong shape is a ValueError naming the argument.
py::array_t<float, py::array::c_style | py::array::forcecast> shaped(const py::object& value, const char* name,
                                                                    std::vector<py::ssize_t> tail, py::ssize_t n)
{
    auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(value);
    if (!a) throw py::value_error(msg("Model.from_arrays: ", name, " is not a numeric array"));
    bool ok = a.ndim() == py::ssize_t(tail.size() + 1) && (n < 0 || a.shape(0) == n);
    for (std::size_t i = 0; ok && i < tail.size(); ++i) ok = tail[i] < 0 || a.shape(py::ssize_t(i + 1)) == tail[i];
    if (!ok) {
        std::string want = tail.empty() ? "(N," : "(N";
        for (py::ssize_t t : tail) want += t < 0 ? ", K" : msg(", ", t);
        std::string got = "(";
        for (py::ssize_t i = 0; i < a.ndim(); ++i) got += msg(i ? ", " : "", a.shape(i));
        throw py::value_error(msg("Model.from_arrays: ", name, " must have shape ", want, ")",
                                  n >= 0 ? msg(" with N = ", n) : std::string(), ", got ", got, a.ndim() == 1 ? ",)" : ")"));
    }
    return a;
}

/// SH degree of an sh_rest array of shape (N, R, 3): R = (d+1)^2 - 1.
int degreeOfRest(py::ssize_t rest)
{
    for (int d = 0; d <= 3; ++d)
        if (shCoeffCount(d) - 1 == rest) return d;
    throw py::value_error(msg("Model.from_arrays: sh_rest holds ", rest,
                              " coefficients per channel; SH degrees 0..3 hold 0, 3, 8 or 15"));
}

GaussianCloud modelFromArrays(const py::object& positions, const py::object& scales, const py::object& rotations,
                              const py::object& opacities, const py::object& shDc, const py::object& shRest,
                              bool dropInvalid)
{
    const auto p = shaped(positions, "positions", {3}, -1);
    const py::ssize_t n = p.shape(0);
    const auto s = shaped(scales, "scales", {3}, n);
    const auto r = shaped(rotations, "rotations", {4}, n);
    const auto o = shaped(opacities, "opacities", {}, n);
    const auto dc = shaped(shDc, "sh_dc", {3}, n);
    const auto rest = shRest.is_none() ? py::array_t<float, py::array::c_style | py::array::forcecast>(std::vector<py::ssize_t>{n, 0, 3})
                                       : shaped(shRest, "sh_rest", {-1, 3}, n);
    GaussianCloud g;
    g.resize(std::size_t(n), degreeOfRest(rest.shape(1)));
    std::copy(p.data(), p.data() + 3 * n, g.means.begin());
    std::copy(s.data(), s.data() + 3 * n, g.logScales.begin());
    std::copy(r.data(), r.data() + 4 * n, g.rotations.begin());
    std::copy(o.data(), o.data() + n, g.opacities.begin());
    const py::ssize_t restFloats = 3 * rest.shape(1);
    for (py::ssize_t i = 0; i < n; ++i) {
        float* sh = g.shOf(std::size_t(i));
        std::copy(dc.data() + 3 * i, dc.data() + 3 * i + 3, sh);
        std::copy(rest.data() + restFloats * i, rest.data() + restFloats * (i + 1), sh + 3);
    }
    ReadOptions rules;
    rules.dropInvalid = dropInvalid;
    ReadReport report;
    applyReadRules("Model.from_arrays", g, rules, &report);
    if (g.empty())
        throw InputError(report.dropped ? msg("Model.from_arrays: no Gaussians left after dropping ", report.dropped, " unusable ones")
                                        : std::string("Model.from_arrays: the arrays hold no Gaussians (Model() is the empty model)"));
    return g;
}

void bindModelArrays(py::class_<GaussianCloud>& model)
{
    model.def_property_readonly(
        "positions", [](py::object self) { auto& g = cloudOf(self); return floatView(self, g.means.data(), {py::ssize_t(g.size()), 3}, {3, 1}); },
        "(N, 3) float32 centres: a view onto the model (writing to it changes the model).");
    model.def_property_readonly(
        "scales", [](py::object self) { auto& g = cloudOf(self); return floatView(self, g.logScales.data(), {py::ssize_t(g.size()), 3}, {3, 1}); },
        "(N, 3) float32 log standard deviations (scale = exp), a view.");
    model.def_property_readonly(
        "rotations", [](py::object self) { auto& g = cloudOf(self); return floatView(self, g.rotations.data(), {py::ssize_t(g.size()), 4}, {4, 1}); },
        "(N, 4) float32 quaternions w, x, y, z (as stored: not normalised), a view.");
    model.def_property_readonly(
        "opacities", [](py::object self) { auto& g = cloudOf(self); return floatView(self, g.opacities.data(), {py::ssize_t(g.size())}, {1}); },
        "(N,) float32 opacity logits (alpha = sigmoid), a view.");
    model.def_property_readonly(
        "sh", [](py::object self) {
            auto& g = cloudOf(self);
            return floatView(self, g.sh.data(), {py::ssize_t(g.size()), g.shCoeffs(), 3}, {g.shStride(), 3, 1});
        },
        "(N, K, 3) float32 SH coefficients, K = (sh_degree + 1)**2, coefficient 0 the DC term, RGB last; a view.");
    model.def_property_readonly(
        "sh_dc", [](py::object self) { auto& g = cloudOf(self); return floatView(self, g.sh.data(), {py::ssize_t(g.size()), 3}, {g.shStride(), 1}); },
        "(N, 3) float32 DC coefficients (graphdeco f_dc_0..2): a strided view of sh[:, 0, :].");
    model.def_property_readonly(
        "sh_rest", [](py::object self) {
            auto& g = cloudOf(self);
            return floatView(self, g.sh.data() + 3, {py::ssize_t(g.size()), g.shCoeffs() - 1, 3}, {g.shStride(), 3, 1});
        },
        "(N, K-1, 3) float32 higher-band coefficients, RGB last (graphdeco's f_rest_* are channel-major:\n"
        "f_rest_{c*(K-1)+j} = sh_rest[:, j, c]); a strided view of sh[:, 1:, :].");
}

void bindModel(py::module_& m)
{
    py::class_<GaussianCloud> model(m, "Model",
                                    "A 3D Gaussian Splatting model with the raw (pre-activation) parameters 3DGS stores.\n"
                                    "Its arrays are numpy views onto the model's own storage: no copies.");
    model.def(py::init<>(), "An empty model.");
    model.def_static("from_arrays", &modelFromArrays, py::arg("positions"), py::arg("scales"), py::arg("rotations"),
                     py::arg("opacities"), py::arg("sh_dc"), py::arg("sh_rest") = py::none(), py::kw_only(),
                     py::arg("drop_invalid") = false,
                     "A model from numpy arrays (copied): positions (N,3), scales (N,3) log, rotations (N,4) wxyz,\n"
                     "opacities (N,) logits, sh_dc (N,3), sh_rest (N,K-1,3) or None (SH degree 0).\n"
                     "A wrong shape is a ValueError naming the array; NaN/Inf or values that overflow in use are\n"
                     "a splatwarp.Error (a ValueError) naming the Gaussian and property, unless drop_invalid.");
    model.def("__len__", &GaussianCloud::size);
    model.def_property_readonly("sh_degree", [](const GaussianCloud& g) { return g.shDegree; }, "SH degree, 0..3.");
    model.def("copy", [](const GaussianCloud& g) { return g; }, "A deep copy.");
    model.def("__repr__", [](const GaussianCloud& g) { return msg("<splatwarp.Model of ", g.size(), " Gaussians, SH degree ", g.shDegree, ">"); });
    bindModelArrays(model);
}

void bindReadWrite(py::module_& m)
{
    m.def(
        "read",
        [](const py::object& path, bool dropInvalid) {
            const LibraryTurn turn;
            const std::string p = pathOf(path);
            py::gil_scoped_release release;
            return readModelFile(p, dropInvalid);
        },
        py::arg("path"), py::kw_only(), py::arg("drop_invalid") = false,
        "Read a model in any format the CLI reads (graphdeco or compressed PLY, .splat, .spz, .glb, .vdb points),\n"
        "detected by content. Bad input raises splatwarp.Error with the message the CLI prints.");
    m.def(
        "write",
        [](const GaussianCloud& model, const py::object& path, int spzVersion) {
            const LibraryTurn turn;
            const std::string p = pathOf(path);
            WriteOptions options;
            options.spzVersion = spzVersion;
            const GaussianCloud copy = model; // checked, then written, while other threads may change the views
            py::gil_scoped_release release;
            writeGaussians(p, copy, options);
        },
        py::arg("model"), py::arg("path"), py::kw_only(), py::arg("spz_version") = WriteOptions().spzVersion,
        "Write a model in the format its extension names: .ply (graphdeco), .compressed.ply, .splat, .spz\n"
        "(spz_version 3 or 4), .glb, .vdb (point grid). Written atomically.");
    m.def("set_progress", &setProgressEnabled, py::arg("enabled"), "Print the library's progress lines on stderr (default off).");
}

} // namespace
} // namespace splatwarp::python

PYBIND11_MODULE(splatwarp, m)
{
    using namespace splatwarp::python;
    m.doc() = "splatwarp: deform 3D Gaussian Splatting models; read, write, render and judge them.";
    splatwarp::registerVdbPointFormat();
#ifdef SPLATWARP_WITH_CUDA
    splatwarp::cuda::registerBackends(); // device='auto'|'cuda' as in the CLI
#endif
    bindErrors(m);
    bindModel(m);
    bindReadWrite(m);
    bindJobs(m);
}
