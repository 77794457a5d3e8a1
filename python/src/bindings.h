// The native part of the Python package (docs/python.md): rodfit._core, bound with pybind11.
// Each file binds one part of the library; the pure-Python rodfit/__init__.py turns paths, dicts
// and numpy arrays into what these take. No algorithm lives here: every call is one of the
// library's entry points, with the GIL released while it runs.
#pragma once

#include <string>

#include <pybind11/pybind11.h>

namespace rodfit_python {

namespace py = pybind11;

/// The Python exception types InputError and ProfileError (carrying file, line, key, message)
/// and the translation of rodfit's C++ errors into them.
void BindErrors(py::module_& m);
/// Experiment (a parsed experiment / scene YAML) and Profile (a read profile JSON).
void BindInputs(py::module_& m);
/// Runtime: the fitted rod at haptic rate (rodfit/runtime/runtime.h).
void BindRuntime(py::module_& m);
/// synth, fit, simulate, rollout (rodfit/pipeline/synthesize.h, rodfit/pipeline/run.h).
void BindPipeline(py::module_& m);

/// A JSON text as Python objects (json.loads): how documents (the profile, motion_fit.json)
/// cross into Python with the same structure and the same doubles (both sides round-trip them).
py::object JsonToPython(const std::string& text);

}  // namespace rodfit_python
