// The native part of the Python package (docs/python.md): rodfit._core, bound with pybind11.
// Each file binds one part of the library; the pure-Python rodfit/__init__.py turns paths, dicts
// and numpy arrays into what these take. No algorithm lives here: every call is one of the
// library's entry points, with the GIL released while it runs.
#pragma once

#include <map>
#include <set>
#include <string>
#include <vector>

#include <pybind11/pybind11.h>

#include "rodfit/model/settings_archive.h"

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

/// The settings a Python caller gave by keyword (`given`: key -> value; a key left out keeps the
/// configuration's default), read through the configurations' Serialize: each value checked
/// against its declared range or words (a word's hyphens and underscores alike: free_roll is
/// free-roll). A bad value throws std::invalid_argument ("key: must be ..."; Python's
/// ValueError). After every configuration is read, CheckAllRead refuses a key none declares
/// (TypeError, as Python does an unexpected keyword).
class DictSettings final : public rodfit::SettingsArchive {
 public:
  explicit DictSettings(const py::dict& given);
  void CheckAllRead() const;

  bool reading() const override { return true; }
  void Integer(const char* key, int* value, int lo, int hi) override;
  void Count(const char* key, int* value, int lo, int hi) override;
  void Number(const char* key, double* value, double lo, double hi) override;
  void Positive(const char* key, double* value) override;
  void Bool(const char* key, bool* value) override;
  void Choice(const char* key, int* index, const std::vector<std::string>& words,
              const std::string& expected) override;
  void IntegerList(const char* key, std::vector<int>* value) override;
  void Require(const char*) override {}
  bool Has(const char* key) const override { return given_.count(key) > 0; }
  /// A configuration's own check across its values (MotionFitOptions' range > 1).
  void Check(bool ok, const char* key, const std::string& message) override;

 private:
  const py::object* Take(const char* key);
  [[noreturn]] void Fail(const char* key, const std::string& message) const;
  long long IntegerOf(const char* key, const py::object& v, const std::string& want);
  double NumberOf(const char* key, const py::object& v);

  std::map<std::string, py::object> given_;
  std::set<std::string> read_;
};

}  // namespace rodfit_python
