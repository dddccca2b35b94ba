#include "PyCommon.h"

#include <algorithm>
#include <vector>

#include "ReadArgs.h"
#include "core/Error.h"

namespace py = pybind11;

namespace splatwarp::python {

std::string pathOf(const py::handle& path)
{
    const py::module_ os = py::module_::import("os");
    const py::object text = os.attr("fspath")(path);
    if (!py::isinstance<py::str>(text)) throw py::type_error("a path must be a str or os.PathLike of str");
    std::string bytes = os.attr("fsencode")(text).cast<std::string>();
    if (bytes.find('\0') != std::string::npos) throw py::value_error("embedded null byte in a path");
    return bytes;
}

LibraryTurn::LibraryTurn()
{
    static std::mutex turns;
    py::gil_scoped_release release; // the call holding the turn may need the GIL to finish
    mLock = std::unique_lock<std::mutex>(turns);
}

GaussianCloud readModelFile(const std::string& path, bool dropInvalid) { return cli::readModel(path, dropInvalid); }

void checkModelInMemory(const std::string& name, GaussianCloud& cloud)
{
    cloud.checkConsistent();
    if (cloud.empty()) throw InputError(msg(name, ": the model holds no Gaussians"));
    applyReadRules(name, cloud);
}

GaussianCloud modelOrPath(const py::handle& value, std::string& name, const std::string& inMemory)
{
    if (py::isinstance<GaussianCloud>(value)) {
        name = inMemory;
        GaussianCloud cloud = value.cast<const GaussianCloud&>();
        checkModelInMemory(name, cloud);
        return cloud;
    }
    name = pathOf(value);
    py::gil_scoped_release release;
    return readModelFile(name, false);
}

void parseSettings(CLI::App& app, CLI::App* sub, const std::string& function, const py::kwargs& settings)
{
    std::vector<std::string> args{sub->get_name()};
    for (const auto& [key, value] : settings) {
        const std::string name = py::str(key);
        std::string flag = "--" + name;
        std::replace(flag.begin(), flag.end(), '_', '-');
        const CLI::Option* option = sub->get_option_no_throw(flag);
        if (!option || option->get_positional() || option == sub->get_help_ptr() || option == sub->get_help_all_ptr() ||
            name.find('-') != std::string::npos)
            throw py::type_error(msg(function, "() got an unexpected keyword argument '", name, "'"));
        if (value.is_none()) continue;
        const bool isBool = py::isinstance<py::bool_>(value);
        if (option->get_expected_min() == 0) { // a flag: True gives it
            if (!isBool) throw py::type_error(msg(function, "(): ", name, " must be True or False"));
            if (value.cast<bool>()) args.push_back(flag);
            continue;
        }
        args.push_back(flag);
        args.push_back(isBool ? (value.cast<bool>() ? "true" : "false") : std::string(py::str(value)));
    }
    cli::addCommonChecks(app);
    std::reverse(args.begin(), args.end()); // CLI11 takes a vector of arguments last first
    try {
        app.parse(args);
    } catch (const CLI::ParseError& e) {
        throw py::value_error(msg(function, "(): ", e.what()));
    }
}

void bindErrors(py::module_& m)
{
    static py::exception<Error> error(m, "Error", PyExc_ValueError);
    error.attr("__doc__") = "A splatwarp error (bad input, an unreadable or unwritable file, a bad setting); its message\n"
                            "is the one the CLI prints after 'splatwarp: error: '.";
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const Error& e) {
            PyErr_SetString(error.ptr(), printable(e.what()).c_str());
        }
    });
}

} // namespace splatwarp::python
