// rodfit._core: the module, its errors and its inputs (docs/python.md).
#include <exception>
#include <string>

#include <pybind11/stl.h>

#include "bindings.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/runtime/profile.h"
#include "rodfit/version.h"
#include "rodfit/vision/camera_file.h"

namespace rodfit_python {

namespace {

// The exception types, created once with the module and kept for the translator (which runs
// with the GIL held). Leaked on purpose: they live as long as the interpreter.
PyObject* input_error_type = nullptr;
PyObject* profile_error_type = nullptr;

// Raises `type` with the one-line message and the place as attributes; line None when unknown.
void Raise(PyObject* type, const std::string& what, const std::string& file, int line,
           const std::string& key, const std::string& message) {
  py::object error = py::reinterpret_borrow<py::object>(type)(what);
  error.attr("file") = file;
  error.attr("line") = line > 0 ? py::object(py::int_(line)) : py::object(py::none());
  error.attr("key") = key;
  error.attr("message") = message;
  PyErr_SetObject(type, error.ptr());
}

}  // namespace

void BindErrors(py::module_& m) {
  // Subclasses of ValueError: bad input is a bad value, and `except ValueError` catches it.
  input_error_type = PyErr_NewExceptionWithDoc(
      "rodfit._core.InputError",
      "A mistake in an input (experiment, scene, observation file, camera): str() is one line "
      "'FILE:LINE: KEY: message'; the attributes file, line (int or None), key and message hold "
      "its parts.",
      PyExc_ValueError, nullptr);
  profile_error_type = PyErr_NewExceptionWithDoc(
      "rodfit._core.ProfileError",
      "A profile that cannot be used: str() is 'FILE: KEY: message'; attributes file, line "
      "(None), key, message.",
      PyExc_ValueError, nullptr);
  m.attr("InputError") = py::handle(input_error_type);
  m.attr("ProfileError") = py::handle(profile_error_type);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const rodfit::InputError& e) {
      Raise(input_error_type, e.what(), e.file, e.line, e.key, e.message);
    } catch (const rodfit::ProfileError& e) {
      Raise(profile_error_type, e.what(), e.file, 0, e.key, e.message);
    } catch (const rodfit::CameraFileError& e) {
      Raise(input_error_type, e.what(), e.file, 0, e.key, e.what());
    }
  });
}

py::object JsonToPython(const std::string& text) {
  return py::module_::import("json").attr("loads")(text);
}

void BindInputs(py::module_& m) {
  py::class_<rodfit::Experiment>(
      m, "Experiment", py::dynamic_attr(),
      "An experiment or scene as rodfit reads it (docs/formats.md): made by "
      "rodfit.experiment(path or dict) or load_experiment / parse_experiment here.")
      .def_property_readonly("path", [](const rodfit::Experiment& e) { return e.path; },
                             "the YAML file's path (names it in messages, anchors relative paths)")
      .def(
          "_use_text_file",
          [](rodfit::Experiment& e, const std::string& path) { e.path = path; },
          "An experiment parsed from text (a dict): the file holding that text, which the "
          "entry points read again (the profile's input digests, synth's experiment.yaml).")
      .def_property_readonly("case_names",
                             [](const rodfit::Experiment& e) {
                               std::vector<std::string> names;
                               for (const rodfit::LoadCase& c : e.scene.cases)
                                 names.push_back(c.name);
                               return names;
                             },
                             "the cases' names, in order")
      .def_property_readonly("moving",
                             [](const rodfit::Experiment& e) { return bool(e.scene.dynamics); },
                             "True for a scene with a dynamics: block")
      .def_property_readonly("length", [](const rodfit::Experiment& e) { return e.scene.rod.length; },
                             "rod.length [m]")
      .def_property_readonly("segments",
                             [](const rodfit::Experiment& e) { return e.scene.rod.segments; },
                             "rod.segments");
  m.def("load_experiment",
        [](const std::string& path, bool parameters_optional) {
          return rodfit::LoadExperiment(path, parameters_optional);
        },
        py::arg("path"),
        py::arg("parameters_optional") = false, py::call_guard<py::gil_scoped_release>(),
        "Reads and validates an experiment / scene YAML file. Raises InputError (file:line:key).");
  m.def("parse_experiment",
        [](const std::string& text, const std::string& path, bool parameters_optional) {
          return rodfit::ParseExperiment(text, path, parameters_optional);
        },
        py::arg("text"), py::arg("path"),
        py::arg("parameters_optional") = false, py::call_guard<py::gil_scoped_release>(),
        "The same from the YAML's text; `path` names it in messages and anchors relative file "
        "paths (its folder).");

  py::class_<rodfit::Profile>(m, "Profile",
                              "A profile JSON as read and validated (rodfit/runtime/profile.h).")
      .def_property_readonly("path", [](const rodfit::Profile& p) { return p.path; })
      .def_property_readonly("version", [](const rodfit::Profile& p) { return p.version; })
      .def_property_readonly("length", [](const rodfit::Profile& p) { return p.scene.rod.length; },
                             "rod.length [m]")
      .def_property_readonly("segments",
                             [](const rodfit::Profile& p) { return p.scene.rod.segments; })
      .def_property_readonly(
          "values",
          [](const rodfit::Profile& p) {
            py::dict out;
            for (const rodfit::Parameter& q : p.parameters) out[py::str(q.name)] = q.value;
            return out;
          },
          "{parameter name: the value the rod uses [SI]}");
  m.def(
      "load_profile",
      [](const std::string& path, const std::map<std::string, double>& overrides) {
        rodfit::ProfileReadOptions options;
        options.overrides = overrides;
        return rodfit::LoadProfile(path, options);
      },
      py::arg("path"), py::arg("overrides") = std::map<std::string, double>{},
      "Reads a profile JSON; `overrides` {name: value [SI]} supply undetermined (null) values "
      "or replace others. Raises ProfileError (file: key: message).");
  m.def(
      "parse_profile",
      [](const std::string& text, const std::string& path,
         const std::map<std::string, double>& overrides) {
        rodfit::ProfileReadOptions options;
        options.overrides = overrides;
        return rodfit::ParseProfile(text, path, options);
      },
      py::arg("text"), py::arg("path"), py::arg("overrides") = std::map<std::string, double>{},
      "The same from the JSON text; `path` names it in messages.");
}

}  // namespace rodfit_python

PYBIND11_MODULE(_core, m) {
  m.doc() = "rodfit's native module; use the package `rodfit` (docs/python.md).";
  m.attr("__version__") = RODFIT_VERSION;
  rodfit_python::BindErrors(m);
  rodfit_python::BindInputs(m);
  rodfit_python::BindRuntime(m);
  rodfit_python::BindPipeline(m);
}
