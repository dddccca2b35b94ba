#include "PyCommon.h"

#include <algorithm>
#include <vector>

#include "ReadArgs.h"
#include "core/Error.h"

namespace py = pybind11;

namespace splatwarp::python {

std::string pathOf(const py::handle& path)
{
    const py::object text = py::module_::import("os").attr("fspath")(path);
    if (!py::isinstance<py::str>(text)) throw py::type_error("a path must be a str or os.PathLike of str");
    return text.cast<std::string>();
}

GaussianCloud readModelFile(const std::string& path, bool dropInvalid) { return cli::readModel(path, dropInvalid); }

GaussianCloud modelOrPath(const py::handle& value, std::string& name)
{
    if (py::isinstance<GaussianCloud>(value)) {
        name = "(model)";
        return value.cast<const GaussianCloud&>();
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
        if (!option || option->get_positional() || name.find('-') != std::string::npos)
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
