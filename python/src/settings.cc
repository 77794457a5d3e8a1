// Settings given by keyword (bindings.h, DictSettings): a configuration's Serialize visited over
// the keywords a Python caller gave, so that the defaults, ranges and words are the ones the
// command line and the files are read with (rodfit/model/settings_archive.h), never repeated in
// the binding or in rodfit/__init__.py.
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "bindings.h"

namespace rodfit_python {
namespace {

std::string Show(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.10g", v);
  return text;
}

// Python's spelling of a word: underscores where the command line has hyphens (free_roll).
std::string PythonWord(std::string word) {
  for (char& c : word)
    if (c == '-') c = '_';
  return word;
}

// "'a', 'b' or 'c'".
std::string QuotedOr(const std::vector<std::string>& words) {
  std::string out;
  for (size_t k = 0; k < words.size(); ++k)
    out += (k == 0 ? "'" : k + 1 == words.size() ? " or '" : ", '") + words[k] + "'";
  return out;
}

}  // namespace

DictSettings::DictSettings(const py::dict& given) {
  for (const auto& item : given) given_[py::cast<std::string>(item.first)] =
      py::reinterpret_borrow<py::object>(item.second);
}

void DictSettings::CheckAllRead() const {
  for (const auto& [key, value] : given_)
    if (!read_.count(key)) throw py::type_error("unexpected keyword argument '" + key + "'");
}

const py::object* DictSettings::Take(const char* key) {
  const auto it = given_.find(key);
  if (it == given_.end()) return nullptr;
  read_.insert(key);
  return &it->second;
}

void DictSettings::Fail(const char* key, const std::string& message) const {
  throw std::invalid_argument(std::string(key) + ": " + message);
}

long long DictSettings::IntegerOf(const char* key, const py::object& v, const std::string& want) {
  // Any integer (numpy's too, through __index__); bool is an int in Python, but True for a
  // count is a mistake.
  if (!py::isinstance<py::bool_>(v)) {
    if (PyObject* index = PyNumber_Index(v.ptr())) {
      const long long x = PyLong_AsLongLong(index);
      Py_DECREF(index);
      if (!(x == -1 && PyErr_Occurred())) return x;
    }
    PyErr_Clear();
  }
  Fail(key, want + ", got " + py::cast<std::string>(py::repr(v)));
}

void DictSettings::Integer(const char* key, int* value, int lo, int hi) {
  const py::object* v = Take(key);
  if (!v) return;
  const std::string range =
      "must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  const long long x = IntegerOf(key, *v, range);
  if (x < lo || x > hi) Fail(key, range + ", got " + std::to_string(x));
  *value = static_cast<int>(x);
}

void DictSettings::Count(const char* key, int* value, int lo, int hi) {
  Integer(key, value, lo, hi);
}

double DictSettings::NumberOf(const char* key, const py::object& v) {
  // Any real number (numpy's too, through __float__), not a bool or a text.
  double x = 0.0;
  if (!py::isinstance<py::bool_>(v) && !py::isinstance<py::str>(v)) {
    x = PyFloat_AsDouble(v.ptr());
    if (x == -1.0 && PyErr_Occurred()) {
      PyErr_Clear();
    } else {
      if (!std::isfinite(x)) Fail(key, "must be finite, got " + Show(x));
      return x;
    }
  }
  Fail(key, "expected a number, got " + py::cast<std::string>(py::repr(v)));
}

void DictSettings::Number(const char* key, double* value, double lo, double hi) {
  const py::object* v = Take(key);
  if (!v) return;
  const double x = NumberOf(key, *v);
  if (x < lo || x > hi)
    Fail(key, "must be in [" + Show(lo) + ", " + Show(hi) + "], got " + Show(x));
  *value = x;
}

void DictSettings::Positive(const char* key, double* value) {
  const py::object* v = Take(key);
  if (!v) return;
  const double x = NumberOf(key, *v);
  if (!(x > 0.0)) Fail(key, "must be > 0, got " + Show(x));
  *value = x;
}

void DictSettings::Bool(const char* key, bool* value) {
  const py::object* v = Take(key);
  if (!v) return;
  if (!py::isinstance<py::bool_>(*v))
    Fail(key, "expected True or False, got " + py::cast<std::string>(py::repr(*v)));
  *value = py::cast<bool>(*v);
}

void DictSettings::Choice(const char* key, int* index, const std::vector<std::string>& words,
                          const std::string& expected) {
  (void)expected;  // the command line's words; Python's are spelled with underscores
  const py::object* v = Take(key);
  if (!v) return;
  std::vector<std::string> python_words;
  for (const std::string& w : words) python_words.push_back(PythonWord(w));
  const std::string wrong = "must be " + QuotedOr(python_words) + ", got " +
                            py::cast<std::string>(py::repr(*v));
  if (!py::isinstance<py::str>(*v)) Fail(key, wrong);
  const std::string word = py::cast<std::string>(*v);
  for (size_t k = 0; k < words.size(); ++k)
    if (PythonWord(word) == python_words[k]) {
      *index = static_cast<int>(k);
      return;
    }
  Fail(key, wrong);
}

void DictSettings::IntegerList(const char* key, std::vector<int>* value) {
  const py::object* v = Take(key);
  if (!v) return;
  if (!py::isinstance<py::sequence>(*v) || py::isinstance<py::str>(*v))
    Fail(key, "expected a list of integers, got " + py::cast<std::string>(py::repr(*v)));
  std::vector<int> list;
  for (const py::handle item : py::reinterpret_borrow<py::sequence>(*v)) {
    const long long x = IntegerOf(key, py::reinterpret_borrow<py::object>(item),
                                  "expected a list of integers");
    if (x < -(1LL << 30) || x > (1LL << 30)) Fail(key, "entry " + std::to_string(x) + " is out of range");
    list.push_back(static_cast<int>(x));
  }
  *value = list;
}

void DictSettings::Check(bool ok, const char* key, const std::string& message) {
  if (!ok) Fail(key, message);
}

}  // namespace rodfit_python
