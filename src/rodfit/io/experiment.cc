// Reading and validating the experiment / scene YAML (see experiment.h, docs/formats.md).
// yaml-cpp gives the tree and the marks; every check and message is here. A Field carries a
// value with its dotted key path and 1-based line, so each error names where it is.
#include "rodfit/io/experiment.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>  // cross product
#include <yaml-cpp/yaml.h>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment_blocks.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/model/rod.h"
#include "rodfit/model/rod_radius.h"
#include "rodfit/model/markup_nesting.h"
#include "rodfit/vision/camera_file.h"  // kMaxImageSidePx, a constant (io links no vision)

namespace rodfit {
namespace {

namespace fs = std::filesystem;
namespace blocks = experiment_blocks;

// Below this sine of the angle between clamp tangent and normal the Gram–Schmidt normal keeps
// fewer than three significant digits; such an input is taken to be a mistake.
constexpr double kMinClampSine = 1e-3;
constexpr size_t kMaxCaseNameLength = 100;

std::string Join(const std::vector<std::string>& words) {
  std::string out;
  for (const auto& w : words) out += (out.empty() ? "" : ", ") + w;
  return out;
}

// Numbers in messages: as a person would type them, not the round-trip digits of FormatDouble.
std::string Show(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.10g", v);
  return buffer;
}

bool Contains(const std::vector<std::string>& words, const std::string& w) {
  return std::find(words.begin(), words.end(), w) != words.end();
}

int LineOf(const YAML::Node& node, int fallback) {
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? mark.line + 1 : fallback;
}

struct Field {
  YAML::Node node;
  std::string key;   // dotted path, e.g. "cases[0].clamp.normal"; empty for the document
  int line = 0;      // line of the value (of the key when the value has no mark)
  int key_line = 0;  // line of the key; 0 for the document
};

// A mapping's entries, with the keys its block declares (experiment_blocks.h, or a
// configuration's or a kind's declaration): Reader::Find and Reader::Require refuse a key the
// block does not declare, so that the declaration stays the one list of the block's keys.
struct Entries : std::map<std::string, Field> {
  std::vector<std::string> declared;
  bool checked = false;  // built by Reader::Map (a collecting pass's empty entries are not)
};

// A key read that its block does not declare: the reader and the block's table disagree.
void CheckDeclared(const Entries& entries, const std::string& name) {
  if (entries.checked && !Contains(entries.declared, name))
    throw std::logic_error("experiment reader: key '" + name + "' is not declared by its block");
}

// The checks shared by every block; all failures are InputErrors in `file`.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void Fail(int line, const std::string& key, const std::string& message) const {
    throw InputError(file_, line, key, message);
  }
  [[noreturn]] void Fail(const Field& f, const std::string& message) const {
    Fail(f.line, f.key, message);
  }

  // The entries of a mapping, each key checked against `allowed` and for duplicates.
  Entries Map(const Field& f, const std::vector<std::string>& allowed) const {
    if (!f.node.IsMap()) Fail(f, "expected a mapping with keys " + Join(allowed));
    Entries entries;
    entries.declared = allowed;
    entries.checked = true;
    for (auto it = f.node.begin(); it != f.node.end(); ++it) {
      const int key_line = LineOf(it->first, f.line);
      if (!it->first.IsScalar()) Fail(key_line, f.key, "expected a plain key");
      const std::string name = it->first.Scalar();
      const std::string key = f.key.empty() ? name : f.key + "." + name;
      if (!Contains(allowed, name)) {
        // The key as written may be anything, of any length: it is echoed cut short.
        const std::string shown = ClipForMessage(name);
        Fail(key_line, f.key.empty() ? shown : f.key + "." + shown,
             "unknown key (allowed: " + Join(allowed) + ")");
      }
      if (entries.count(name)) Fail(key_line, key, "duplicate key");
      // A null value's mark points at the next token, often on a later line.
      const int line = it->second.IsNull() ? key_line : LineOf(it->second, key_line);
      entries[name] = Field{it->second, key, line, key_line};
    }
    return entries;
  }

  const Field& Require(const Entries& entries, const Field& parent, const std::string& name) const {
    CheckDeclared(entries, name);
    const auto it = entries.find(name);
    if (it == entries.end()) {
      Fail(parent.key_line, parent.key.empty() ? name : parent.key + "." + name,
           "missing required key");
    }
    return it->second;
  }

  static const Field* Find(const Entries& entries, const std::string& name) {
    CheckDeclared(entries, name);
    const auto it = entries.find(name);
    return it == entries.end() ? nullptr : &it->second;
  }

  std::vector<Field> Sequence(const Field& f) const {
    if (!f.node.IsSequence()) Fail(f, "expected a list");
    std::vector<Field> items;
    for (size_t i = 0; i < f.node.size(); ++i) {
      const int line = LineOf(f.node[i], f.line);
      items.push_back(Field{f.node[i], f.key + "[" + std::to_string(i) + "]", line, line});
    }
    return items;
  }

  double Number(const Field& f) const {
    double value = 0.0;
    if (f.node.IsNull()) Fail(f, "expected a number, got nothing");
    if (!f.node.IsScalar()) Fail(f, "expected a number");
    try {
      value = f.node.as<double>();
    } catch (const YAML::Exception&) {
      Fail(f, "expected a number, got '" + ClipForMessage(f.node.Scalar()) + "'");
    }
    if (!std::isfinite(value)) {
      Fail(f, "must be finite, got '" + ClipForMessage(f.node.Scalar()) + "'");
    }
    return value;
  }

  int Integer(const Field& f) const {
    if (!f.node.IsScalar()) Fail(f, "expected an integer");
    try {
      return f.node.as<int>();
    } catch (const YAML::Exception&) {
      Fail(f, "expected an integer, got '" + ClipForMessage(f.node.Scalar()) + "'");
    }
  }

  // An integer in [lo, hi]; text that is no integer (1e9, 3.5, 99999999999999) gets the same
  // message with the range, so a limit is always named.
  int IntegerIn(const Field& f, long long lo, long long hi) const {
    const std::string range =
        "must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    if (!f.node.IsScalar()) Fail(f, range);
    long long v = 0;
    try {
      v = f.node.as<long long>();
    } catch (const YAML::Exception&) {
      Fail(f, range + ", got '" + ClipForMessage(f.node.Scalar()) + "'");
    }
    if (v < lo || v > hi) Fail(f, range + ", got " + std::to_string(v));
    return static_cast<int>(v);
  }

  bool Bool(const Field& f) const {
    if (!f.node.IsScalar()) Fail(f, "expected true or false");
    try {
      return f.node.as<bool>();
    } catch (const YAML::Exception&) {
      Fail(f, "expected true or false, got '" + ClipForMessage(f.node.Scalar()) + "'");
    }
  }

  std::string Text(const Field& f) const {
    if (!f.node.IsScalar() || f.node.Scalar().empty()) Fail(f, "expected a non-empty text");
    return f.node.Scalar();
  }

  Vec3 Vector3(const Field& f) const {
    if (!f.node.IsSequence() || f.node.size() != 3) {
      Fail(f, "expected a list of 3 numbers" +
                  (f.node.IsSequence() ? ", got " + std::to_string(f.node.size()) : ""));
    }
    const std::vector<Field> items = Sequence(f);
    return Vec3(Number(items[0]), Number(items[1]), Number(items[2]));
  }

  double Positive(const Field& f) const {
    const double v = Number(f);
    if (!(v > 0.0)) Fail(f, "must be > 0, got " + Show(v));
    return v;
  }

  double NonNegative(const Field& f) const {
    const double v = Number(f);
    if (v < 0.0) Fail(f, "must be >= 0, got " + Show(v));
    return v;
  }

  double InRange(const Field& f, double lo, double hi) const {
    const double v = Number(f);
    if (v < lo || v > hi) {
      Fail(f, "must be in [" + Show(lo) + ", " + Show(hi) + "], got " + Show(v));
    }
    return v;
  }

  // A path inside the YAML file, relative to the file's folder (docs/formats.md).
  std::string Path(const Field& f, const std::string& directory) const {
    fs::path p(Text(f));
    if (p.is_relative() && !directory.empty()) p = fs::path(directory) / p;
    return p.lexically_normal().string();
  }
  // A file the reader opens now (a start shape, a path, a velocity): one that cannot be opened
  // is named at its key's line, so the message says which entry of which YAML file wants it.
  std::string ReadablePath(const Field& f, const std::string& directory) const {
    const std::string path = Path(f, directory);
    std::error_code ec;
    if (!fs::exists(path, ec)) Fail(f, "cannot open " + path + ": no such file");
    if (!fs::is_regular_file(path, ec)) Fail(f, "cannot open " + path + ": not a regular file");
    return path;
  }

 private:
  std::string file_;
};

// With `density_elsewhere` (parameters.linear_density is given) the rod's linear_density must be
// left out: one value, the parameter's. With `density_optional` (a profile supplies the
// material) it may be left out and is NaN until the profile's rod fills it.
RodSpec ReadRod(const Reader& r, const Field& f, bool density_elsewhere, bool density_optional,
                const std::string& directory) {
  const Entries m = r.Map(f, blocks::kRod.keys);
  RodSpec rod;
  rod.length = r.Positive(r.Require(m, f, "length"));
  if (const Field* vs = Reader::Find(m, "vertex_s")) {
    // Vertices at given arc lengths (a vertex at every tracked marker): 0 first, the length
    // last, increasing; the segment count follows (and must agree when also given).
    const std::vector<Field> items = r.Sequence(*vs);
    if (items.size() < 3 || items.size() > static_cast<size_t>(kMaxSegments) + 1)
      r.Fail(*vs, "expected 3 to " + std::to_string(kMaxSegments + 1) + " arc lengths, got " +
                      std::to_string(items.size()));
    for (size_t k = 0; k < items.size(); ++k) {
      const double v = r.Number(items[k]);
      if (k == 0 && v != 0.0) r.Fail(items[k], "must be 0 (the clamped end)");
      if (k + 1 == items.size() && std::abs(v - rod.length) > 1e-12 * rod.length)
        r.Fail(items[k], "must be rod.length " + Show(rod.length) + " (the last vertex)");
      if (k > 0 && !(v > rod.vertex_s.back()))
        r.Fail(items[k], "must be larger than the one before");
      rod.vertex_s.push_back(k + 1 == items.size() ? rod.length : v);
    }
    rod.segments = static_cast<int>(items.size()) - 1;
    if (const Field* segments = Reader::Find(m, "segments")) {
      if (r.IntegerIn(*segments, 2, kMaxSegments) != rod.segments)
        r.Fail(*segments, "disagrees with vertex_s (" + std::to_string(rod.segments) + " segments)");
    }
  } else {
    const Field& segments = r.Require(m, f, "segments");
    rod.segments = r.IntegerIn(segments, 2, kMaxSegments);
  }
  const Field& radius = r.Require(m, f, "radius");
  rod.radius = r.Positive(radius);
  if (const std::string why = CheckRodRadius(rod.radius, rod.length); !why.empty())
    r.Fail(radius, why);
  if (density_elsewhere) {
    if (const Field* d = Reader::Find(m, "linear_density"))
      r.Fail(*d, "given twice: here and as parameters.linear_density (keep one)");
  } else if (const Field* d = Reader::Find(m, "linear_density"); d || !density_optional) {
    const Field& density = d ? *d : r.Require(m, f, "linear_density");
    rod.linear_density = r.NonNegative(density);
    // 0 is a massless rod; any other value in the row's physical range.
    const std::string why =
        rod.linear_density == 0.0
            ? std::string()
            : CheckMaterialParameterRange(*FindMaterialParameter("linear_density"),
                                          rod.linear_density);
    if (!why.empty()) r.Fail(density, why);
  } else {
    rod.linear_density = std::numeric_limits<double>::quiet_NaN();
  }
  if (const Field* k = Reader::Find(m, "rest_curvature")) rod.rest_curvature = r.Vector3(*k);
  if (const Field* shape = Reader::Find(m, "rest_shape")) {
    // A centre-line at rest (the rod's natural shape): CSV s,x,y,z or x,y,z, optionally
    // nx,ny,nz on its first row (d1 at s = 0, which the clamp's normal is; default +z).
    const std::string file = r.ReadablePath(*shape, directory);
    const CsvTable table = CsvTable::Read(file);
    if (table.num_rows() < 3)
      throw InputError(file, 0, "", "a rest shape needs at least 3 points, got " +
                                        std::to_string(table.num_rows()));
    const std::vector<double> x = table.Column("x"), y = table.Column("y"), z = table.Column("z");
    Mat3X points(3, table.num_rows());
    for (int k = 0; k < table.num_rows(); ++k) points.col(k) = Vec3(x[k], y[k], z[k]);
    std::vector<double> s;
    if (table.HasColumn("s")) s = table.Column("s");
    Vec3 normal = Vec3::UnitZ();
    if (table.HasColumn("nx"))
      normal = Vec3(table.Column("nx")[0], table.Column("ny")[0], table.Column("nz")[0]);
    try {
      RestCurvatureOfCentreline(s, points, normal, rod.length, &rod.rest_curvature_s,
                                &rod.rest_curvature_profile);
    } catch (const std::invalid_argument& e) {
      throw InputError(file, 0, "", e.what());
    }
  }
  return rod;
}

// One entry of `parameters:`. A damping's `fit: true` needs motion (a dynamics: block), as does
// linear_density at all (elsewhere it is rod.linear_density, a weight, not a parameter).
Parameter ReadParameter(const Reader& r, const Field& f, const std::string& name, bool moving) {
  if (!f.node.IsMap()) {
    std::string shape;  // "{value: ..., fit: ..., min: ..., max: ...}"
    for (const std::string& key : blocks::kParameterEntry.keys)
      shape += (shape.empty() ? "{" : ", ") + key + ": ...";
    r.Fail(f, "expected a mapping " + shape + "}");
  }
  const MaterialParameterInfo* row = FindMaterialParameter(name);
  if (row && row->kind == ParameterKind::kMass && !moving)
    r.Fail(f.key_line, f.key,
           "only in a moving scene (a dynamics: block), where motion and forces determine it; "
           "elsewhere give rod." + name);
  const Entries m = r.Map(f, blocks::kParameterEntry.keys);
  Parameter p;
  p.name = name;
  p.line = f.key_line;
  const Field& value = r.Require(m, f, "value");
  // spring_stiffness = 0 means no springs and zero damping none (docs/model.md, "What a scene
  // builds"); every stiffness of the rod is > 0. A zone's own parameter is a spring stiffness.
  p.value = row && row->positive ? r.Positive(value) : r.NonNegative(value);
  if (row) {  // the row's physical range, as the profile reader, --set and the exports check it
    const std::string why = CheckMaterialParameterRange(*row, p.value);
    if (!why.empty()) r.Fail(value, why);
  }
  p.start = p.value;
  if (const Field* fit = Reader::Find(m, "fit")) {
    p.fit = r.Bool(*fit);
    if (p.fit && row && row->kind == ParameterKind::kDamping && !moving)
      r.Fail(fit->line, fit->key,
             "damping is identified from motion: fitting it needs a dynamics: block and "
             "observation sequences (else give its value, fit: false)");
  }
  if (p.fit && !(p.value > 0.0)) {
    r.Fail(value, "a fitted parameter must be > 0 (fitted in log space)");
  }
  const Field* min = Reader::Find(m, "min");
  const Field* max = Reader::Find(m, "max");
  if (min) p.min = r.Positive(*min);
  if (max) p.max = r.Positive(*max);
  if (p.min && p.max && !(*p.min < *p.max)) {
    r.Fail(*max, "must be greater than min (" + Show(*p.min) + ")");
  }
  if (p.min && p.value < *p.min) r.Fail(value, "is below min (" + Show(*p.min) + ")");
  if (p.max && p.value > *p.max) r.Fail(value, "is above max (" + Show(*p.max) + ")");
  return p;
}

void ReadParameters(const Reader& r, const Field& f, Experiment* ex,
                    const std::vector<std::string>& zone_parameters) {
  std::vector<std::string> allowed;
  for (const MaterialParameterInfo& row : MaterialParameters()) allowed.push_back(row.name);
  allowed.insert(allowed.end(), zone_parameters.begin(), zone_parameters.end());
  const Entries m = r.Map(f, allowed);
  const bool moving = ex->scene.dynamics.has_value();
  for (const auto& [name, field] : m) ex->parameters[name] = ReadParameter(r, field, name, moving);
  for (const std::string& name : zone_parameters) r.Require(m, f, name);
  const bool section = ex->scene.section.has_value();
  for (const MaterialParameterInfo& row : MaterialParameters()) {
    // The ring's stiffness is read only for a scene with a cross-section (tissue paper §4).
    if (row.needs_section && !section) continue;
    if (row.required) r.Require(m, f, row.name);
  }
  // Each value where its row says (the rod's density into the rod: it sets the masses and
  // weights).
  for (const auto& [name, p] : ex->parameters) {
    const MaterialParameterInfo* row = FindMaterialParameter(name);
    if (row && row->needs_section && !section) continue;
    AssignMaterialParameter(name, p.value, &ex->scene.material, &ex->scene.rod);
  }
}

// `rotation_prior_deg: sigma` of a clamp or an end clamp: (0, 90] degrees.
std::optional<double> ReadRotationPrior(const Reader& r, const Entries& m) {
  const Field* f = Reader::Find(m, "rotation_prior_deg");
  if (!f) return std::nullopt;
  const double sigma = r.Positive(*f);
  if (sigma > 90.0) r.Fail(*f, "must be at most 90 (degrees per axis), got " + Show(sigma));
  return sigma;
}

// `position_prior: sigma` of a held point [m]: (0, 0.1] (a point misplaced by more than 10 cm
// is a wrong scene, not a nuisance).
std::optional<double> ReadPositionPrior(const Reader& r, const Entries& m) {
  const Field* f = Reader::Find(m, "position_prior");
  if (!f) return std::nullopt;
  const double sigma = r.Positive(*f);
  if (sigma > 0.1) r.Fail(*f, "must be at most 0.1 (metres per axis), got " + Show(sigma));
  return sigma;
}

Clamp ReadClamp(const Reader& r, const Field& f) {
  const Entries m = r.Map(f, blocks::kHeldFrame.keys);
  Clamp clamp;
  clamp.rotation_prior_deg = ReadRotationPrior(r, m);
  clamp.position_prior = ReadPositionPrior(r, m);
  clamp.position = r.Vector3(r.Require(m, f, "position"));
  const Field& tangent = r.Require(m, f, "tangent");
  const Field& normal = r.Require(m, f, "normal");
  clamp.tangent = r.Vector3(tangent);
  clamp.normal = r.Vector3(normal);
  const double t = clamp.tangent.norm();
  const double n = clamp.normal.norm();
  if (!(t > 0.0)) r.Fail(tangent, "must not be zero");
  if (!(n > 0.0)) r.Fail(normal, "must not be zero");
  if (clamp.tangent.cross(clamp.normal).norm() < kMinClampSine * t * n) {
    r.Fail(normal, "is (nearly) parallel to the tangent");
  }
  return clamp;
}

// An observation entry's keys as its kind declares them (EntryKeys), over the entry's YAML
// mapping. Collecting, it only records the keys declared (the kind's allowed keys); reading, it
// checks and reads each key the entry holds.
class YamlEntryKeys final : public EntryKeys {
 public:
  YamlEntryKeys(const Reader& r, const Field& entry, const Entries& keys, const Experiment& ex,
                const LoadCase& load_case, const std::vector<std::string>& points, bool moving,
                bool reading)
      : r_(r), entry_(entry), keys_(keys), ex_(ex), load_case_(load_case), points_(points),
        moving_(moving), reading_(reading) {}

  const std::vector<std::string>& declared() const { return declared_; }

  bool moving() const override { return moving_; }
  const LoadCase& load_case() const override { return load_case_; }
  const RodSpec& rod() const override { return ex_.scene.rod; }

  void Path(const char* key, std::string* path, bool required) override {
    if (const Field* f = Take(key, required)) *path = r_.Path(*f, ex_.directory);
  }
  void Positive(const char* key, double* value, bool required) override {
    if (const Field* f = Take(key, required)) *value = r_.Positive(*f);
  }
  void Number(const char* key, double* value, double lo, double hi) override {
    if (const Field* f = Take(key, false)) *value = r_.InRange(*f, lo, hi);
  }
  void Fraction(const char* key, double* value) override {
    if (const Field* f = Take(key, false)) {
      *value = r_.Number(*f);
      if (*value < 0.0 || *value >= 1.0) r_.Fail(*f, "must be in [0, 1), got " + Show(*value));
    }
  }
  void Integer(const char* key, int* value, int lo, int hi) override {
    if (const Field* f = Take(key, false)) *value = r_.IntegerIn(*f, lo, hi);
  }
  void ArcLengths(const char* key, std::vector<double>* s) override {
    if (const Field* f = Take(key, false)) {
      const std::vector<Field> items = r_.Sequence(*f);
      if (items.empty()) r_.Fail(*f, "must not be empty");
      for (const Field& item : items) s->push_back(r_.InRange(item, 0.0, ex_.scene.rod.length));
    }
  }
  void GraspArcLength(const char* key, std::vector<double>* s) override {
    const Field* f = Take(key, true);
    if (!f) return;
    if (!f->node.IsScalar()) r_.Fail(*f, "expected one arc length [m] (the grasped point)");
    const double v = r_.InRange(*f, 0.0, ex_.scene.rod.length);
    if (v < 0.5 * ex_.scene.rod.length / ex_.scene.rod.segments)
      r_.Fail(*f, "the grasp is at the clamp (s rounds to vertex 0)");
    s->push_back(v);
  }
  // `roi: [x0, y0, x1, y1]` (docs/formats.md, "Observation entries"): pixel corners, x1 and y1
  // exclusive. Whether it fits the image is known only when the image is read (the extraction
  // names the image then).
  void Roi(const char* key, std::optional<std::array<int, 4>>* roi) override {
    const Field* f = Take(key, false);
    if (!f) return;
    if (!f->node.IsSequence() || f->node.size() != 4) {
      r_.Fail(*f, "expected [x0, y0, x1, y1] (4 pixel corners)" +
                      (f->node.IsSequence() ? ", got " + std::to_string(f->node.size()) + " values"
                                            : std::string()));
    }
    const std::vector<Field> items = r_.Sequence(*f);
    std::array<int, 4> corners{};
    for (int k = 0; k < 4; ++k) corners[k] = r_.IntegerIn(items[k], 0, kMaxImageSidePx);
    if (corners[2] <= corners[0])
      r_.Fail(items[2], "x1 must exceed x0 (" + std::to_string(corners[0]) + ")");
    if (corners[3] <= corners[1])
      r_.Fail(items[3], "y1 must exceed y0 (" + std::to_string(corners[1]) + ")");
    *roi = corners;
  }
  void Choice(const char* key, double* value,
              const std::vector<std::pair<std::string, double>>& choices,
              const std::string& expected) override {
    const Field* f = Take(key, false);
    if (!f) return;
    const std::string word = r_.Text(*f);
    for (const auto& [name, number] : choices)
      if (word == name) {
        *value = number;
        return;
      }
    r_.Fail(*f, expected + ", got '" + ClipForMessage(word) + "'");
  }
  void Frame(const char* key, Eigen::Matrix3d* rotation, Vec3* translation) override {
    const Field* frame = Take(key, false);
    if (!frame) return;
    const Entries fm = r_.Map(*frame, blocks::kDeviceFrame.keys);
    if (const Field* t = Reader::Find(fm, "translation")) *translation = r_.Vector3(*t);
    if (const Field* rot = Reader::Find(fm, "rotation")) {
      const std::vector<Field> rows = r_.Sequence(*rot);
      if (rows.size() != 3)
        r_.Fail(*rot, "expected 3 rows of 3 numbers (the device's axes in the scene, row by row)");
      Eigen::Matrix3d R;
      for (int i = 0; i < 3; ++i) R.row(i) = r_.Vector3(rows[i]).transpose();
      // A rotation to the file's precision: orthonormal (a scaled or sheared matrix would change
      // the forces' size) with determinant +1 (no mirror image).
      const double off = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
      if (!(off <= 1e-6) || !(R.determinant() > 0.0)) {
        r_.Fail(*rot, "is not a rotation (R^T R differs from I by " + Show(off) +
                          ", det R = " + Show(R.determinant()) + ")");
      }
      *rotation = R;
    }
  }
  void HeldPoint(const char* key, std::string* point, bool required) override {
    const Field* f = Take(key, required);
    if (!f) return;
    *point = r_.Text(*f);
    if (!Contains(points_, *point))
      r_.Fail(*f, "this case holds no '" + ClipForMessage(*point) + "' (it holds: " +
                      Join(points_) + ")");
  }
  void Exclusive(const char* key, const char* other) override {
    if (!reading_) return;
    const Field* a = Reader::Find(keys_, key);
    const Field* b = Reader::Find(keys_, other);
    if (a && b) r_.Fail(b->key_line, b->key, "give either " + std::string(key) + " or " + other +
                                                 ", not both");
  }
  void Check(bool ok, const char* key, const std::string& message) override {
    if (!reading_ || ok) return;
    if (const Field* f = Reader::Find(keys_, key)) r_.Fail(*f, message);
    r_.Fail(entry_, message);
  }

 private:
  // Declares `key`; reading, its field when the entry holds it (a required key it does not hold
  // is an error at the entry's line), else null.
  const Field* Take(const char* key, bool required) {
    declared_.push_back(key);
    if (!reading_) return nullptr;
    const Field* f = Reader::Find(keys_, key);
    if (!f && required) r_.Require(keys_, entry_, key);
    return f;
  }

  const Reader& r_;
  const Field& entry_;
  const Entries& keys_;
  const Experiment& ex_;
  const LoadCase& load_case_;
  const std::vector<std::string>& points_;
  bool moving_, reading_;
  std::vector<std::string> declared_;
};

// "a, b and c".
std::string JoinAnd(const std::vector<std::string>& words) {
  std::string out;
  for (size_t k = 0; k < words.size(); ++k)
    out += (k == 0 ? "" : k + 1 == words.size() ? " and " : ", ") + words[k];
  return out;
}

// An entry of a case's `observations:`: its type names its kind, whose declared keys (in this
// scene, static or moving) are the only ones allowed and are read here.
ObservationSpec ReadObservation(const Reader& r, const Field& f, const Experiment& ex,
                                const LoadCase& load_case, const std::vector<std::string>& points,
                                const ObservationEntryKinds& kinds) {
  const bool moving = ex.scene.dynamics.has_value();
  const std::vector<std::string> names = kinds.Names(false);
  // Every key some kind takes, static or moving: any other is unknown.
  std::vector<std::string> all = {"type"};
  static const Entries kNoKeys;  // collecting reads none
  for (const std::string& name : names)
    for (const bool mode : {false, true}) {
      ObservationSpec scratch;
      YamlEntryKeys collect(r, f, kNoKeys, ex, load_case, points, mode, false);
      kinds.DeclareKeys(name, &collect, &scratch);
      for (const std::string& key : collect.declared())
        if (!Contains(all, key)) all.push_back(key);
    }
  // A key no kind takes, in an entry whose type is known, is told with that type's keys: the
  // union of every kind's is too long a line to read.
  if (f.node.IsMap()) {
    const YAML::Node type_node = f.node["type"];
    if (type_node && type_node.IsScalar() && Contains(names, type_node.Scalar())) {
      const std::string type_name = type_node.Scalar();
      std::vector<std::string> own = {"type"};
      for (const bool mode : {moving, !moving}) {
        ObservationSpec scratch;
        YamlEntryKeys collect(r, f, kNoKeys, ex, load_case, points, mode, false);
        kinds.DeclareKeys(type_name, &collect, &scratch);
        for (const std::string& key : collect.declared())
          if (!Contains(own, key)) own.push_back(key);
      }
      for (auto it = f.node.begin(); it != f.node.end(); ++it) {
        if (!it->first.IsScalar() || Contains(all, it->first.Scalar())) continue;
        const std::string key = ClipForMessage(it->first.Scalar());
        r.Fail(LineOf(it->first, f.line), f.key.empty() ? key : f.key + "." + key,
               "unknown key (allowed for type " + type_name + ": " + Join(own) + ")");
      }
    }
  }
  const Entries m = r.Map(f, all);
  ObservationSpec o;
  o.line = f.line;
  const Field& type = r.Require(m, f, "type");
  o.type = r.Text(type);
  if (!Contains(names, o.type)) {
    r.Fail(type, "unknown observation type '" + ClipForMessage(o.type) +
                     "' (allowed: " + Join(names) + ")");
  }
  // A moving scene is observed over time: its entries are sequences, one measurement per frame
  // (the kinds that may move, docs/formats.md, "Observation sequences").
  if (moving && !Contains(kinds.Names(true), o.type))
    r.Fail(type, "a moving scene (dynamics:) is observed by " + JoinAnd(kinds.Names(true)) +
                     " sequences only, not " + o.type);
  ObservationSpec scratch;
  YamlEntryKeys here(r, f, m, ex, load_case, points, moving, false);
  kinds.DeclareKeys(o.type, &here, &scratch);
  YamlEntryKeys there(r, f, m, ex, load_case, points, !moving, false);
  kinds.DeclareKeys(o.type, &there, &scratch);
  std::vector<std::string> allowed = {"type"};
  allowed.insert(allowed.end(), here.declared().begin(), here.declared().end());
  // A sequence's key in a static scene, in the order the kind declares them, then any other.
  if (!moving)
    for (const std::string& name : there.declared())
      if (const Field* field = Reader::Find(m, name); field && !Contains(allowed, name))
        r.Fail(field->key_line, field->key, "only for a sequence (a scene with a dynamics: block)");
  for (const auto& [name, field] : m) {
    if (!Contains(allowed, name))
      r.Fail(field.key_line, field.key,
             "not allowed for type " + o.type + " (allowed: " + Join(allowed) + ")");
  }
  YamlEntryKeys read(r, f, m, ex, load_case, points, moving, true);
  kinds.DeclareKeys(o.type, &read, &o);
  return o;
}

Interval ReadInterval(const Reader& r, const Field& f, double length, const Entries& m) {
  Interval iv;
  const Field& from = r.Require(m, f, "from");
  const Field& to = r.Require(m, f, "to");
  iv.from = r.InRange(from, 0.0, length);
  iv.to = r.InRange(to, 0.0, length);
  if (!(iv.from < iv.to)) r.Fail(to, "must be greater than from (" + Show(iv.from) + ")");
  return iv;
}

// Top-level `section:` (tissue paper §4): the cross-section ring used by pokes.
SectionSpec ReadSection(const Reader& r, const Field& f) {
  const Entries m = r.Map(f, blocks::kSection.keys);
  SectionSpec spec;
  spec.radius = r.Positive(r.Require(m, f, "radius"));
  if (const Field* n = Reader::Find(m, "nodes")) {
    spec.nodes = r.IntegerIn(*n, 8, kMaxSectionNodes);
  }
  if (const Field* h = Reader::Find(m, "h_factor")) spec.h_factor = r.Positive(*h);
  if (const Field* st = Reader::Find(m, "stop_factor")) spec.stop_factor = r.Positive(*st);
  return spec;
}

// Top-level `springs:`: attachment zones, each with spring_stiffness or its own
// parameter. Returns the zone parameters' names (they become allowed parameter keys).
std::vector<std::string> ReadSprings(const Reader& r, const Field& f, Experiment* ex) {
  std::vector<std::string> names;
  std::vector<std::pair<Interval, int>> seen;
  for (const Field& item : r.Sequence(f)) {
    const Entries m = r.Map(item, blocks::kSpringZone.keys);
    const Interval iv = ReadInterval(r, item, ex->scene.rod.length, m);
    for (const auto& [other, line] : seen) {
      if (iv.from < other.to && other.from < iv.to) {
        r.Fail(item, "overlaps the zone at line " + std::to_string(line));
      }
    }
    seen.emplace_back(iv, item.line);
    SpringZone zone{iv.from, iv.to, ""};
    if (const Field* p = Reader::Find(m, "parameter")) {
      zone.parameter = r.Text(*p);
      const MaterialParameterInfo* row = FindMaterialParameter(zone.parameter);
      if (row && row->kind == ParameterKind::kSpring) {
        zone.parameter.clear();
      } else if (row) {
        r.Fail(*p, "'" + ClipForMessage(zone.parameter) +
                       "' is a rod parameter, not a spring stiffness");
      } else if (!Contains(names, zone.parameter)) {
        names.push_back(zone.parameter);
      }
    }
    ex->scene.springs.push_back(zone);
  }
  return names;
}

// A unit direction from a vector key; zero is an error at the key.
Vec3 Direction(const Reader& r, const Field& f) {
  const Vec3 v = r.Vector3(f);
  if (!(v.norm() > 0.0)) r.Fail(f, "must not be zero");
  return v;
}

EndClamp ReadEndClamp(const Reader& r, const Field& f) {
  const Entries m = r.Map(f, blocks::kHeldFrame.keys);
  EndClamp ec;
  ec.rotation_prior_deg = ReadRotationPrior(r, m);
  ec.position_prior = ReadPositionPrior(r, m);
  ec.position = r.Vector3(r.Require(m, f, "position"));
  const Field& tangent = r.Require(m, f, "tangent");
  ec.tangent = Direction(r, tangent);
  if (const Field* normal = Reader::Find(m, "normal")) {
    ec.normal = Direction(r, *normal);
    if (ec.tangent.cross(*ec.normal).norm() < kMinClampSine * ec.tangent.norm() * ec.normal->norm())
      r.Fail(*normal, "is (nearly) parallel to the tangent");
  }
  if (ec.rotation_prior_deg && !ec.normal)
    r.Fail(*Reader::Find(m, "rotation_prior_deg"),
           "needs the end clamp's normal (a fitted rotation turns a whole frame)");
  return ec;
}

// `start:` straight | previous | a CSV of the ordered centre-line (s,x,y,z or x,y,z).
StartShape ReadStart(const Reader& r, const Field& f, const Experiment& ex, int index) {
  StartShape start;
  const std::string text = r.Text(f);
  if (text == "straight") return start;
  if (text == "previous") {
    if (index == 0) r.Fail(f, "the first case has no previous case to start from");
    start.kind = StartShape::Kind::kPrevious;
    return start;
  }
  start.kind = StartShape::Kind::kPoints;
  start.file = r.ReadablePath(f, ex.directory);
  const CsvTable table = CsvTable::Read(start.file);
  const std::vector<double> x = table.Column("x"), y = table.Column("y"), z = table.Column("z");
  if (table.num_rows() < 2)
    throw InputError(start.file, 0, "", "a start shape needs at least 2 points, got " +
                                            std::to_string(table.num_rows()));
  start.points.resize(3, table.num_rows());
  for (int k = 0; k < table.num_rows(); ++k) start.points.col(k) = Vec3(x[k], y[k], z[k]);
  if (table.HasColumn("s")) {
    start.s = table.Column("s");
    for (int k = 1; k < table.num_rows(); ++k)
      if (!(start.s[k] > start.s[k - 1]))
        throw InputError(start.file, table.line(k), "s", "must increase from row to row");
  } else {
    for (int k = 1; k < table.num_rows(); ++k)
      if (start.points.col(k) == start.points.col(k - 1))
        throw InputError(start.file, table.line(k), "x",
                         "repeats the point before it (a start shape's points must differ)");
  }
  return start;
}

// A CSV of samples over time: column t [s], strictly increasing, and the columns `a` (required),
// `b` and `c` (optional, both or neither of each triple).
TimeSeries ReadTimeSeries(const Reader& r, const Field& f, const Experiment& ex,
                          const std::vector<std::string>& a, const std::vector<std::string>& b,
                          const std::vector<std::string>& c) {
  TimeSeries series;
  series.file = r.ReadablePath(f, ex.directory);
  const CsvTable table = CsvTable::Read(series.file);
  if (table.num_rows() < 1) throw InputError(series.file, 0, "", "no rows");
  series.t = table.Column("t");
  for (int k = 1; k < table.num_rows(); ++k)
    if (!(series.t[k] > series.t[k - 1]))
      throw InputError(series.file, table.line(k), "t", "must increase from row to row");
  auto triple = [&](const std::vector<std::string>& names, std::vector<Vec3>* out) {
    if (names.empty() || !table.HasColumn(names[0])) return;
    const std::vector<double> x = table.Column(names[0]), y = table.Column(names[1]),
                              z = table.Column(names[2]);
    for (int k = 0; k < table.num_rows(); ++k) out->emplace_back(x[k], y[k], z[k]);
  };
  for (const std::string& name : a)
    if (!table.HasColumn(name)) throw InputError(series.file, 1, name, "missing column");
  triple(a, &series.a);
  triple(b, &series.b);
  triple(c, &series.c);
  if (!c.empty() && table.HasColumn("qw")) {
    // A frame as a unit quaternion (w, x, y, z; a robot's or a tracker's pose): the held
    // material frame is the rotation's columns, d1 = R e_x (the normal), d3 = R e_z (the
    // tangent), as a Cosserat rod's directors are the columns of its rotation.
    if (!series.b.empty())
      throw InputError(series.file, 1, "qw", "give the frame once: tx..nz or qw,qx,qy,qz");
    const std::vector<double> w = table.Column("qw"), x = table.Column("qx"),
                              y = table.Column("qy"), z = table.Column("qz");
    for (int k = 0; k < table.num_rows(); ++k) {
      Eigen::Quaterniond q(w[k], x[k], y[k], z[k]);
      const double norm = q.norm();
      if (!(norm > 0.5 && norm < 2.0))
        throw InputError(series.file, table.line(k), "qw",
                         "not a unit quaternion (norm " + Show(norm) + ")");
      const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
      series.b.push_back(R.col(2));
      series.c.push_back(R.col(0));
    }
  }
  if (!c.empty() && series.b.empty() != series.c.empty())
    throw InputError(series.file, 1, series.b.empty() ? b[0] : c[0],
                     "orientation needs both the tangent (tx,ty,tz) and normal (nx,ny,nz) columns "
                     "(or qw,qx,qy,qz)");
  for (size_t k = 0; k < series.c.size(); ++k) {
    const Vec3& t = series.b[k];
    const Vec3& n = series.c[k];
    if (!(t.norm() > 0.0) || t.cross(n).norm() < kMinClampSine * t.norm() * n.norm())
      throw InputError(series.file, table.line(static_cast<int>(k)), "nx",
                       "the normal is zero or (nearly) parallel to the tangent");
  }
  return series;
}

// `drive:` [{point: clamp | end_clamp | end_pin | grasp | pins[k], file: path.csv}].
void ReadDrives(const Reader& r, const Field& f, const Experiment& ex, LoadCase* c) {
  for (const Field& item : r.Sequence(f)) {
    const Entries dm = r.Map(item, blocks::kDrive.keys);
    DrivenPoint d;
    const Field& point = r.Require(dm, item, "point");
    d.point = r.Text(point);
    bool held = d.point == "clamp" || (d.point == "end_clamp" && c->end_clamp) ||
                (d.point == "end_pin" && c->end_pin) || (d.point == "grasp" && c->grasp);
    if (d.point.rfind("pins[", 0) == 0 && d.point.back() == ']') {
      const std::string digits = d.point.substr(5, d.point.size() - 6);
      held = !digits.empty() && digits.size() < 6 &&
             digits.find_first_not_of("0123456789") == std::string::npos &&
             std::stoul(digits) < c->pins.size();
    }
    if (!held)
      r.Fail(point, "must name a point the case holds (clamp, end_clamp, end_pin, grasp or "
                    "pins[k]), got '" + ClipForMessage(d.point) + "'");
    for (const DrivenPoint& other : c->drives)
      if (other.point == d.point) r.Fail(point, "is driven twice");
    const bool frame = d.point == "clamp" || d.point == "end_clamp";
    d.path = ReadTimeSeries(r, r.Require(dm, item, "file"), ex, {"x", "y", "z"},
                            frame ? std::vector<std::string>{"tx", "ty", "tz"}
                                  : std::vector<std::string>{},
                            frame ? std::vector<std::string>{"nx", "ny", "nz"}
                                  : std::vector<std::string>{});
    c->drives.push_back(std::move(d));
  }
}

// `driven:` [{s, file}]: the held point at arc length s follows the path, the point created
// when the case does not hold it yet. s = 0 is the clamp; s = L the end_clamp or end_pin (an
// end_clamp when the path has a frame, an end_pin else); any other s the grasp or pin there, or
// a new pin. A new point starts at the path's first row.
void ReadDriven(const Reader& r, const Field& f, const Experiment& ex, LoadCase* c) {
  const double L = ex.scene.rod.length;
  for (const Field& item : r.Sequence(f)) {
    const Entries dm = r.Map(item, blocks::kDriven.keys);
    const Field& s_field = r.Require(dm, item, "s");
    const double s = r.InRange(s_field, 0.0, L);
    const Field& file = r.Require(dm, item, "file");
    DrivenPoint d;
    // Read with frame columns allowed; a point that cannot turn refuses them below.
    d.path = ReadTimeSeries(r, file, ex, {"x", "y", "z"}, {"tx", "ty", "tz"}, {"nx", "ny", "nz"});
    const bool has_frame = !d.path.b.empty();
    if (s == 0.0) {
      d.point = "clamp";
    } else if (s == L) {
      if (c->end_clamp) {
        d.point = "end_clamp";
      } else if (c->end_pin) {
        d.point = "end_pin";
      } else if (has_frame) {
        EndClamp ec;
        ec.position = d.path.a.front();
        ec.tangent = d.path.b.front();
        ec.normal = d.path.c.front();
        c->end_clamp = ec;
        d.point = "end_clamp";
      } else {
        c->end_pin = d.path.a.front();
        d.point = "end_pin";
      }
    } else if (c->grasp && c->grasp->s == s) {
      d.point = "grasp";
    } else {
      size_t k = 0;
      while (k < c->pins.size() && c->pins[k].s != s) ++k;
      if (k == c->pins.size()) c->pins.push_back(Pin{s, d.path.a.front(), std::nullopt});
      d.point = "pins[" + std::to_string(k) + "]";
    }
    if (has_frame && d.point != "clamp" && d.point != "end_clamp")
      r.Fail(s_field, "the path has a frame (tx..nz or qw..qz), but the " + d.point +
                          " at s = " + Show(s) + " holds a position only");
    if (!has_frame) {
      d.path.b.clear();
      d.path.c.clear();
    }
    for (const DrivenPoint& other : c->drives)
      if (other.point == d.point) r.Fail(s_field, "drives the " + d.point + " a second time");
    c->drives.push_back(std::move(d));
  }
}

// `initial:` {shape: equilibrium | start | FILE.csv, velocity: zero | path.csv (s,vx,vy,vz)}.
// A shape file is the case's start shape (as `start:`, s,x,y,z or x,y,z), taken as it is.
void ReadInitial(const Reader& r, const Field& f, const Experiment& ex, int index, LoadCase* c) {
  const Entries im = r.Map(f, blocks::kInitial.keys);
  if (const Field* frames = Reader::Find(im, "frames")) {
    // Two consecutive frames of a recording: the shape of the first, taken as it is, and the
    // velocity (second - first) / interval at the same arc lengths.
    if (Reader::Find(im, "shape") || Reader::Find(im, "velocity"))
      r.Fail(*frames, "give either frames or shape and velocity");
    if (c->start.kind != StartShape::Kind::kStraight)
      r.Fail(*frames, "the case has a start: already; give the shape once");
    const std::vector<Field> files = r.Sequence(*frames);
    if (files.size() != 2) r.Fail(*frames, "expected two files: [first.csv, second.csv]");
    const StartShape a = ReadStart(r, files[0], ex, index);
    const StartShape b = ReadStart(r, files[1], ex, index);
    if (a.points.cols() != b.points.cols() || a.s != b.s)
      r.Fail(files[1], "must hold the same points (rows and s) as " + a.file);
    double dt = 0.0;
    if (const Field* fi = Reader::Find(im, "frame_interval")) {
      dt = r.Positive(*fi);
    } else {
      const CsvTable ta = CsvTable::Read(a.file), tb = CsvTable::Read(b.file);
      if (!ta.HasColumn("t") || !tb.HasColumn("t"))
        r.Fail(*frames, "give frame_interval [s] (or a t column in both files)");
      dt = tb.Column("t")[0] - ta.Column("t")[0];
      if (!(dt > 0.0)) r.Fail(files[1], "its t must be later than the first file's");
    }
    c->start = a;
    c->initial.equilibrium = false;
    c->initial.file = b.file;
    c->initial.velocity = (b.points - a.points) / dt;
    // The velocities' arc lengths: the files' s, else the first polyline's own scaled to the
    // rod's length (as a start shape without s is placed on the rod).
    c->initial.velocity_s = a.s;
    if (c->initial.velocity_s.empty()) {
      std::vector<double>& vs = c->initial.velocity_s;
      vs.push_back(0.0);
      for (int k = 1; k < a.points.cols(); ++k)
        vs.push_back(vs.back() + (a.points.col(k) - a.points.col(k - 1)).norm());
      for (double& v : vs) v *= ex.scene.rod.length / vs.back();
    }
    return;
  }
  if (const Field* fi = Reader::Find(im, "frame_interval"))
    r.Fail(*fi, "only with frames: [first.csv, second.csv]");
  if (const Field* shape = Reader::Find(im, "shape")) {
    const std::string text = r.Text(*shape);
    if (text == "equilibrium" || text == "start") {
      c->initial.equilibrium = text == "equilibrium";
    } else {
      if (c->start.kind != StartShape::Kind::kStraight)
        r.Fail(*shape, "the case has a start: already; give the shape once");
      std::error_code ec;
      if (text != "straight" && text != "previous" &&
          !fs::is_regular_file(r.Path(*shape, ex.directory), ec))
        r.Fail(*shape, "must be equilibrium, start or a shape CSV file (s,x,y,z or x,y,z); no "
                       "file '" + ClipForMessage(text) + "'");
      c->start = ReadStart(r, *shape, ex, index);
      c->initial.equilibrium = false;
    }
  }
  const Field* v = Reader::Find(im, "velocity");
  if (v && v->node.IsScalar() && v->node.Scalar() == "zero") v = nullptr;  // at rest (default)
  if (v) {
    c->initial.file = r.ReadablePath(*v, ex.directory);
    const CsvTable table = CsvTable::Read(c->initial.file);
    if (table.num_rows() < 1) throw InputError(c->initial.file, 0, "", "no rows");
    c->initial.velocity_s = table.Column("s");
    const std::vector<double> x = table.Column("vx"), y = table.Column("vy"), z = table.Column("vz");
    c->initial.velocity.resize(3, table.num_rows());
    const double L = ex.scene.rod.length;
    for (int k = 0; k < table.num_rows(); ++k) {
      const double s = c->initial.velocity_s[k];
      // An arc length off the rod is a file for another rod (or in other units): the
      // interpolation would silently clamp it to an end.
      if (!(s >= -1e-9 * L && s <= L * (1.0 + 1e-9)))
        throw InputError(c->initial.file, table.line(k), "s",
                         "must lie on the rod, in [0, " + Show(L) + "] m");
      if (k > 0 && !(s > c->initial.velocity_s[k - 1]))
        throw InputError(c->initial.file, table.line(k), "s", "must increase from row to row");
      c->initial.velocity.col(k) = Vec3(x[k], y[k], z[k]);
    }
  }
}

// The case's name (case<index> when not given): checked as the file name and the message text
// it becomes, unique in the file (name_lines: each name's line).
std::string ReadCaseName(const Reader& r, const Field& f, const Entries& m, int index,
                         std::map<std::string, int>* name_lines) {
  std::string name_text = "case" + std::to_string(index);
  const Field* name = Reader::Find(m, "name");
  if (!name) {
    if (name_lines->count(name_text))
      r.Fail(f, "duplicate case name '" + name_text + "' (give this case a name)");
    (*name_lines)[name_text] = f.line;
    return name_text;
  }
  name_text = r.Text(*name);
  // Names go unquoted into shapes.csv and error messages.
  if (name_text.find_first_of(",\"\n\r") != std::string::npos) {
    r.Fail(*name, "must not contain commas, quotes or line breaks");
  }
  // Names become file names (simulate's CASE.obj, the report's plots): never a path, never a
  // hidden file, never '.' or '..'.
  if (name_text.find_first_of(std::string("/\\\0", 3)) != std::string::npos) {
    r.Fail(*name, "must not contain '/', '\\' or NUL (it is used as a file name), got '" +
                      ClipForMessage(name_text) + "'");
  }
  // A file name has at most 255 bytes (with ".obj" and the report's suffixes), and a name is
  // echoed in messages of at most a line.
  if (name_text.size() > kMaxCaseNameLength) {
    r.Fail(*name, "must have at most " + std::to_string(kMaxCaseNameLength) +
                      " characters (it is used as a file name), got " +
                      std::to_string(name_text.size()) + ": '" + ClipForMessage(name_text) + "'");
  }
  if (name_text[0] == '.') {
    r.Fail(*name, "must not start with '.' (it is used as a file name), got '" +
                      ClipForMessage(name_text) + "'");
  }
  const auto seen = name_lines->find(name_text);
  if (seen != name_lines->end()) {
    r.Fail(*name, "duplicate case name '" + ClipForMessage(name_text) + "' (first at line " +
                      std::to_string(seen->second) + ")");
  }
  (*name_lines)[name_text] = name->line;
  return name_text;
}

// Fitted frames (rotation_prior_deg under `key`) are the static fit's: a moving fit drives its
// held points along paths.
void RequireStaticFrame(const Reader& r, const Entries& m, const char* key, bool prior,
                        const Experiment& ex) {
  if (prior && ex.scene.dynamics)
    r.Fail(*Reader::Find(m, key),
           "rotation_prior_deg fits the frame in a static scene only (not with a dynamics: "
           "block)");
}

// A held point's fitted offset (position_prior), likewise the static fit's only.
void RequireStaticPoint(const Reader& r, const Entries& held, const Experiment& ex) {
  if (const Field* p = Reader::Find(held, "position_prior"); p && ex.scene.dynamics)
    r.Fail(*p, "fits the held point in a static scene only (not with a dynamics: block)");
}

// The clamp and the far end's hold: an end_clamp or an end_pin, not both.
void ReadHeldEnds(const Reader& r, const Field& f, const Entries& m, const Experiment& ex,
                  LoadCase* c) {
  c->clamp = ReadClamp(r, r.Require(m, f, "clamp"));
  RequireStaticFrame(r, m, "clamp", c->clamp.rotation_prior_deg.has_value(), ex);
  RequireStaticPoint(r, r.Map(r.Require(m, f, "clamp"), blocks::kHeldFrame.keys), ex);
  const Field* end_clamp = Reader::Find(m, "end_clamp");
  const Field* end_pin = Reader::Find(m, "end_pin");
  if (end_clamp && end_pin)
    r.Fail(end_pin->key_line, end_pin->key, "s = L is already held by end_clamp: give one");
  if (end_clamp) {
    c->end_clamp = ReadEndClamp(r, *end_clamp);
    RequireStaticFrame(r, m, "end_clamp", c->end_clamp->rotation_prior_deg.has_value(), ex);
    RequireStaticPoint(r, r.Map(*end_clamp, blocks::kHeldFrame.keys), ex);
  }
  if (end_pin) {
    const Entries pm = r.Map(*end_pin, blocks::kEndPin.keys);
    c->end_pin = r.Vector3(r.Require(pm, *end_pin, "position"));
    c->end_pin_position_prior = ReadPositionPrior(r, pm);
    RequireStaticPoint(r, pm, ex);
  }
}

// The loads at s = L (refused where the end is held) and the point moments.
void ReadTipLoads(const Reader& r, const Entries& m, const Experiment& ex, LoadCase* c) {
  const Field* end_clamp = Reader::Find(m, "end_clamp");
  const Field* end_pin = Reader::Find(m, "end_pin");
  const char* held_end = end_clamp ? "end_clamp" : "end_pin";
  if (const Field* tf = Reader::Find(m, "tip_force")) {
    c->tip_force = r.Vector3(*tf);
    if ((end_clamp || end_pin) && c->tip_force.squaredNorm() > 0)
      r.Fail(*tf, std::string("acts on s = L, which the ") + held_end + " holds: remove it");
  }
  if (const Field* tm = Reader::Find(m, "tip_moment")) {
    c->tip_moment = r.Vector3(*tm);
    if (end_clamp && c->tip_moment.squaredNorm() > 0)
      r.Fail(*tm, "acts on s = L, which the end_clamp holds: remove it");
  }
  if (const Field* tm = Reader::Find(m, "tip_moment_follower")) {
    c->tip_moment_follower = r.Vector3(*tm);
    if (end_clamp && c->tip_moment_follower.squaredNorm() > 0)
      r.Fail(*tm, "acts on s = L, which the end_clamp holds: remove it");
  }
  if (const Field* pm = Reader::Find(m, "point_moments")) {
    for (const Field& item : r.Sequence(*pm)) {
      const Entries mm = r.Map(item, blocks::kPointMoment.keys);
      PointMoment p;
      p.s = r.InRange(r.Require(mm, item, "s"), 0.0, ex.scene.rod.length);
      p.moment = r.Vector3(r.Require(mm, item, "moment"));
      c->point_moments.push_back(p);
    }
  }
}

// Pins: each inside (0, L) (the clamp holds s = 0, an end_pin s = L), one per arc length.
void ReadPins(const Reader& r, const Entries& m, const Experiment& ex, LoadCase* c) {
  const Field* pins = Reader::Find(m, "pins");
  if (!pins) return;
  const double L = ex.scene.rod.length;
  std::vector<std::pair<double, int>> seen;
  for (const Field& item : r.Sequence(*pins)) {
    const Entries pm = r.Map(item, blocks::kPin.keys);
    Pin p;
    p.position_prior = ReadPositionPrior(r, pm);
    RequireStaticPoint(r, pm, ex);
    const Field& s_field = r.Require(pm, item, "s");
    p.s = r.Number(s_field);
    if (!(p.s > 0.0 && p.s < L))
      r.Fail(s_field, "must lie inside (0, " + Show(L) + ") (the clamp holds s = 0; use end_pin "
                      "for s = L), got " + Show(p.s));
    for (const auto& [other, line] : seen)
      if (other == p.s) r.Fail(s_field, "another pin holds s = " + Show(p.s) + " (line " +
                                            std::to_string(line) + ")");
    seen.emplace_back(p.s, s_field.line);
    p.position = r.Vector3(r.Require(pm, item, "position"));
    c->pins.push_back(p);
  }
}

// The start shape, and a moving scene's keys (refused in a static one): drives, driven points,
// the tip load's time series, the initial state.
void ReadStartAndMotion(const Reader& r, const Entries& m, const Experiment& ex, int index,
                        LoadCase* c) {
  if (const Field* start = Reader::Find(m, "start")) c->start = ReadStart(r, *start, ex, index);
  for (const char* key : {"drive", "driven", "tip_load", "initial"}) {
    if (const Field* d = Reader::Find(m, key); d && !ex.scene.dynamics)
      r.Fail(*d, "only for a moving scene (a top-level dynamics: block)");
  }
  if (const Field* d = Reader::Find(m, "drive")) ReadDrives(r, *d, ex, c);
  if (const Field* d = Reader::Find(m, "driven")) ReadDriven(r, *d, ex, c);
  if (const Field* t = Reader::Find(m, "tip_load")) {
    const Entries tm = r.Map(*t, blocks::kTipLoad.keys);
    c->tip_load = ReadTimeSeries(r, r.Require(tm, *t, "file"), ex, {"fx", "fy", "fz"},
                                 {"mx", "my", "mz"}, {});
  }
  if (const Field* init = Reader::Find(m, "initial")) ReadInitial(r, *init, ex, index, c);
}

// Point forces, and cuts through the springs.
void ReadPointForcesAndCuts(const Reader& r, const Entries& m, const Experiment& ex,
                            LoadCase* c) {
  if (const Field* pf = Reader::Find(m, "point_forces")) {
    for (const Field& item : r.Sequence(*pf)) {
      const Entries pm = r.Map(item, blocks::kPointForce.keys);
      PointForce p;
      p.s = r.InRange(r.Require(pm, item, "s"), 0.0, ex.scene.rod.length);
      p.force = r.Vector3(r.Require(pm, item, "force"));
      c->point_forces.push_back(p);
    }
  }
  if (const Field* cut = Reader::Find(m, "cut")) {
    if (ex.scene.springs.empty()) r.Fail(*cut, "a cut needs springs to cut (top-level springs:)");
    for (const Field& item : r.Sequence(*cut)) {
      const Entries cm = r.Map(item, blocks::kCut.keys);
      c->cuts.push_back(ReadInterval(r, item, ex.scene.rod.length, cm));
    }
  }
}

// The grasp: a held point off both ends (more than half an edge from the clamp, and from s = L
// where the end is held).
void ReadGrasp(const Reader& r, const Entries& m, const Experiment& ex, LoadCase* c) {
  const Field* grasp = Reader::Find(m, "grasp");
  if (!grasp) return;
  const double L = ex.scene.rod.length;
  const Field* end_clamp = Reader::Find(m, "end_clamp");
  const Field* end_pin = Reader::Find(m, "end_pin");
  const char* held_end = end_clamp ? "end_clamp" : "end_pin";
  const Entries gm = r.Map(*grasp, blocks::kGrasp.keys);
  Grasp g;
  g.position_prior = ReadPositionPrior(r, gm);
  RequireStaticPoint(r, gm, ex);
  const Field& s_field = r.Require(gm, *grasp, "s");
  g.s = r.InRange(s_field, 0.0, ex.scene.rod.length);
  if (g.s < 0.5 * ex.scene.rod.length / ex.scene.rod.segments) {
    r.Fail(s_field, "the grasp is at the clamp (within half an edge of s = 0)");
  }
  if ((end_clamp || end_pin) && g.s >= L - 0.5 * L / ex.scene.rod.segments)
    r.Fail(s_field, std::string("the grasp is at s = L, which the ") + held_end + " holds");
  g.position = r.Vector3(r.Require(gm, *grasp, "position"));
  c->grasp = g;
}

// The poke (a force on the cross-section model) and the symmetry plane (checked against the
// whole case, read by then).
void ReadPokeAndSymmetry(const Reader& r, const Entries& m, const Experiment& ex, LoadCase* c) {
  if (const Field* poke = Reader::Find(m, "poke")) {
    if (!ex.scene.section) r.Fail(*poke, "a poke needs the cross-section model (top-level section:)");
    const Entries pm = r.Map(*poke, blocks::kPoke.keys);
    Poke p;
    p.s = r.InRange(r.Require(pm, *poke, "s"), 0.0, ex.scene.rod.length);
    p.force = r.Vector3(r.Require(pm, *poke, "force"));
    c->poke = p;
  }
  if (const Field* sym = Reader::Find(m, "symmetry")) {
    const Entries sm = r.Map(*sym, blocks::kSymmetry.keys);
    SymmetryPlane plane;
    plane.point = r.Vector3(r.Require(sm, *sym, "point"));
    plane.normal = Direction(r, r.Require(sm, *sym, "normal"));
    c->symmetry = plane;
    const std::string problem =
        SymmetryProblem(ex.scene.rod, ex.scene.gravity, *c, !ex.scene.springs.empty());
    if (!problem.empty()) r.Fail(*sym, problem);
  }
}

// A case's keys are read in the order the format lists them (docs/formats.md), each group by
// its reader above, each key with its own one-line check.
void ReadCase(const Reader& r, const Field& f, int index, Experiment* ex,
              std::map<std::string, int>* name_lines, const ObservationEntryKinds& kinds) {
  const Entries m = r.Map(f, blocks::kCase.keys);
  LoadCase c;
  c.name = ReadCaseName(r, f, m, index, name_lines);
  ReadHeldEnds(r, f, m, *ex, &c);
  ReadTipLoads(r, m, *ex, &c);
  ReadPins(r, m, *ex, &c);
  ReadStartAndMotion(r, m, *ex, index, &c);
  ReadPointForcesAndCuts(r, m, *ex, &c);
  ReadGrasp(r, m, *ex, &c);
  ReadPokeAndSymmetry(r, m, *ex, &c);
  CaseSpec spec;
  spec.line = f.line;
  // The case's held points, as forces.csv and `reaction` observations name them.
  std::vector<std::string> points = {"clamp"};
  if (c.end_clamp) points.push_back("end_clamp");
  if (c.end_pin) points.push_back("end_pin");
  for (size_t k = 0; k < c.pins.size(); ++k) points.push_back("pins[" + std::to_string(k) + "]");
  if (c.grasp) points.push_back("grasp");
  if (const Field* obs = Reader::Find(m, "observations")) {
    for (const Field& item : r.Sequence(*obs)) {
      spec.observations.push_back(ReadObservation(r, item, *ex, c, points, kinds));
    }
  }
  ex->scene.cases.push_back(c);
  ex->cases.push_back(spec);
}

// A settings block (`solver:`, `fit:`, `dynamics:`) as its configuration declares it
// (rodfit/io/settings.h). Collecting, it records the keys declared (the block's allowed keys);
// reading, it checks and reads each key the block holds.
class YamlSettings final : public SettingsArchive {
 public:
  YamlSettings(const Reader& r, const Field& block, const Entries& keys, bool reading)
      : r_(r), block_(block), keys_(keys), reading_(reading) {}

  const std::vector<std::string>& declared() const { return declared_; }

  bool reading() const override { return reading_; }
  void Integer(const char* key, int* value, int lo, int hi) override {
    if (const Field* f = Take(key)) *value = r_.IntegerIn(*f, lo, hi);
  }
  void Count(const char* key, int* value, int lo, int hi) override {
    if (const Field* f = Take(key)) {
      *value = r_.Integer(*f);
      if (*value < lo || *value > hi)
        r_.Fail(*f, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
                        std::to_string(*value));
    }
  }
  void Number(const char* key, double* value, double lo, double hi) override {
    if (const Field* f = Take(key)) *value = r_.InRange(*f, lo, hi);
  }
  void Positive(const char* key, double* value) override {
    if (const Field* f = Take(key)) *value = r_.Positive(*f);
  }
  void Bool(const char* key, bool* value) override {
    if (const Field* f = Take(key)) *value = r_.Bool(*f);
  }
  void Choice(const char* key, int* index, const std::vector<std::string>& words,
              const std::string& expected) override {
    const Field* f = Take(key);
    if (!f) return;
    const std::string word = r_.Text(*f);
    for (size_t k = 0; k < words.size(); ++k)
      if (word == words[k]) {
        *index = static_cast<int>(k);
        return;
      }
    r_.Fail(*f, expected + ", got '" + ClipForMessage(word) + "'");
  }
  void Require(const char* key) override {
    if (reading_) r_.Require(keys_, block_, key);
  }
  bool Has(const char* key) const override { return Reader::Find(keys_, key) != nullptr; }
  void Check(bool ok, const char* key, const std::string& message) override {
    if (!reading_ || ok) return;
    if (const Field* f = Reader::Find(keys_, key)) r_.Fail(*f, message);
    r_.Fail(block_, message);
  }

 private:
  const Field* Take(const char* key) {
    declared_.push_back(key);
    return reading_ ? Reader::Find(keys_, key) : nullptr;
  }

  const Reader& r_;
  const Field& block_;
  const Entries& keys_;
  bool reading_;
  std::vector<std::string> declared_;
};

// Reads a settings block into `config` (its defaults where the block says nothing); returns the
// block's entries.
template <class Config, class... Vocabulary>
Entries ReadSettings(const Reader& r, const Field& f, Config* config,
                     const Vocabulary&... vocabulary) {
  static const Entries kNoKeys;
  Config scratch;
  YamlSettings keys(r, f, kNoKeys, /*reading=*/false);
  Serialize(&keys, &scratch, vocabulary...);
  const Entries m = r.Map(f, keys.declared());
  YamlSettings read(r, f, m, /*reading=*/true);
  Serialize(&read, config, vocabulary...);
  return m;
}

// Before yaml-cpp sees the text: no control characters (binary data; yaml-cpp's messages for
// them name an escape that is not in the file) and at most kMaxYamlNesting levels, so the
// recursive-descent parser never recurses deeper than that.
void CheckYamlText(const std::string& text, const std::string& path) {
  int line = 1;
  for (const char ch : text) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c == '\n') ++line;
    if ((c < 0x20 && c != '\n' && c != '\r' && c != '\t') || c == 0x7f) {
      char code[8];
      std::snprintf(code, sizeof(code), "0x%02x", c);
      throw InputError(path, line, "",
                       std::string("control character ") + code + ": not a YAML text (binary data?)");
    }
  }
  const int depth = MarkupNestingDepth(text);
  if (depth > kMaxYamlNesting) {
    throw InputError(path, 0, "", "nested " + std::to_string(depth) + " levels deep (at most " +
                                      std::to_string(kMaxYamlNesting) + ")");
  }
}

// After parsing, the tree's size with every alias expanded (as the reader walks it): a few
// aliases of aliases stand for billions of nodes. Walked with an explicit stack, stopping at the
// limit, so neither time nor depth grows with what the aliases stand for.
void CheckYamlNodes(const YAML::Node& root, const std::string& path) {
  std::vector<YAML::Node> stack = {root};
  long long count = 1;  // nodes pushed: the stack never holds more than the limit
  while (!stack.empty()) {
    const YAML::Node node = stack.back();
    stack.pop_back();
    count += static_cast<long long>(node.IsMap() ? 2 * node.size() : node.size());
    if (count > kMaxYamlNodes) {
      throw InputError(path, 0, "", "more than " + std::to_string(kMaxYamlNodes) +
                                        " YAML nodes with aliases expanded (the limit)");
    }
    if (node.IsSequence()) {
      for (const YAML::Node& item : node) stack.push_back(item);
    } else if (node.IsMap()) {
      for (const auto& entry : node) {
        stack.push_back(entry.first);
        stack.push_back(entry.second);
      }
    }
  }
}

}  // namespace


Experiment ParseExperiment(const std::string& text, const std::string& path,
                           const ObservationEntryKinds& kinds,
                           const std::vector<std::string>& integrators, bool parameters_optional) {
  CheckYamlText(text, path);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(path, e.mark.line >= 0 ? e.mark.line + 1 : 0, "", e.msg);
  }
  if (root.IsNull()) throw InputError(path, 0, "", "empty file");
  CheckYamlNodes(root, path);

  const Reader r(path);
  Experiment ex;
  ex.path = path;
  ex.directory = fs::path(path).parent_path().string();
  const Field top{root, "", 1, 0};
  const Entries m = r.Map(top, blocks::kDocument.keys);
  const Field* params = Reader::Find(m, "parameters");
  // The rod's density given as a parameter (a row of the rod's, in a moving scene).
  bool density_in_parameters = false;
  for (const MaterialParameterInfo& row : MaterialParameters())
    density_in_parameters |= row.rod_field == &RodSpec::linear_density && params &&
                             params->node.IsMap() && params->node[row.name].IsDefined();
  ex.scene.rod =
      ReadRod(r, r.Require(m, top, "rod"), density_in_parameters, parameters_optional,
              ex.directory);
  if (const Field* section = Reader::Find(m, "section")) ex.scene.section = ReadSection(r, *section);
  std::vector<std::string> zone_parameters;
  if (const Field* springs = Reader::Find(m, "springs")) {
    zone_parameters = ReadSprings(r, *springs, &ex);
  }
  // Before the parameters: whether the scene moves decides which of them may be fitted.
  if (const Field* dynamics = Reader::Find(m, "dynamics")) {
    ex.scene.dynamics.emplace();
    const Entries block = ReadSettings(r, *dynamics, &*ex.scene.dynamics, integrators);
    // Where a fit that cannot use the integrator points: its key, or the block's.
    const Field* integrator = Reader::Find(block, "integrator");
    ex.integrator_line = integrator ? integrator->line : dynamics->key_line;
  }
  // With a profile supplying the material (`simulate --profile`) the block may be left out.
  if (params || !parameters_optional)
    ReadParameters(r, params ? *params : r.Require(m, top, "parameters"), &ex, zone_parameters);
  if (const Field* g = Reader::Find(m, "gravity")) ex.scene.gravity = r.Vector3(*g);
  // `gravity_prior_deg: sigma`: each case's gravity (the camera's tilt) a nuisance of the static
  // fit, (0, 90] degrees per axis.
  if (const Field* g = Reader::Find(m, "gravity_prior_deg")) {
    const double sigma = r.Positive(*g);
    if (sigma > 90.0) r.Fail(*g, "must be at most 90 (degrees per axis), got " + Show(sigma));
    if (ex.scene.dynamics) r.Fail(*g, "fits gravity in a static scene only (not with a dynamics: block)");
    if (!(ex.scene.gravity.norm() > 0.0)) r.Fail(*g, "needs a non-zero gravity to turn");
    ex.scene.gravity_prior_deg = sigma;
  }
  if (const Field* fit = Reader::Find(m, "fit")) {
    ReadSettings(r, *fit, static_cast<FitOptions*>(&ex.fit));
    ex.fit.line = fit->key_line;
  }
  if (const Field* solver = Reader::Find(m, "solver")) ReadSettings(r, *solver, &ex.statics);
  if (ex.scene.dynamics && ex.fit.line > 0) {
    // A moving scene's fit is plain least squares on the sequences (docs/formats.md,
    // "Observation sequences"): the static fit's robust losses and global search are not part
    // of it.
    if (ex.fit.loss != RobustLoss::kNone)
      r.Fail(ex.fit.line, "fit.loss", "a moving scene's fit takes no robust loss (loss: none)");
    if (ex.fit.global) r.Fail(ex.fit.line, "fit.global", "a moving scene's fit has no global search");
  }

  const Field& cases = r.Require(m, top, "cases");
  if (cases.node.IsSequence() && cases.node.size() > static_cast<size_t>(kMaxCases)) {
    r.Fail(cases, "at most " + std::to_string(kMaxCases) + " cases, got " +
                      std::to_string(cases.node.size()));
  }
  const std::vector<Field> items = r.Sequence(cases);
  if (items.empty()) r.Fail(cases, "no cases");
  std::map<std::string, int> name_lines;
  for (size_t k = 0; k < items.size(); ++k) {
    ReadCase(r, items[k], static_cast<int>(k), &ex, &name_lines, kinds);
  }
  return ex;
}

Experiment LoadExperiment(const std::string& path, const ObservationEntryKinds& kinds,
                          const std::vector<std::string>& integrators, bool parameters_optional) {
  // Bounded before yaml-cpp sees it: a regular file of at most kMaxInputFileBytes.
  return ParseExperiment(ReadInputFile(path, "a YAML file", kMaxYamlBytes), path, kinds,
                         integrators, parameters_optional);
}

std::string CameraKey(const ObservationSpec& spec) {
  return spec.camera_index > 0 ? spec.camera + "[" + std::to_string(spec.camera_index) + "]"
                               : spec.camera;
}

}  // namespace rodfit
