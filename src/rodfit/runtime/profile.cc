// The validating profile reader (rodfit/runtime/profile.h). The runtime depends on model and
// solve only, so this reader is separate from the io layer's writer; both take the parameters'
// names and units from the parameter table (rodfit/model/material_parameters.h).
#include "rodfit/runtime/profile.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "rodfit/model/material_parameters.h"
#include "rodfit/model/rod_radius.h"
#include "rodfit/runtime/profile_format.h"

namespace rodfit {
namespace {

using nlohmann::json;
namespace pf = profile_format;

std::string Show(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.10g", v);
  return buffer;
}

// Walks the document with the dotted key of each value, so that every failure names it.
class Reader {
 public:
  explicit Reader(std::string path) : path_(std::move(path)) {}

  [[noreturn]] void Fail(const std::string& key, const std::string& message) const {
    throw ProfileError(path_, key, message);
  }

  const json& Object(const json& v, const std::string& key,
                     const std::vector<std::string>& allowed) const {
    if (!v.is_object()) Fail(key, "must be an object");
    for (const auto& item : v.items())
      if (std::find(allowed.begin(), allowed.end(), item.key()) == allowed.end())
        Fail(Join(key, item.key()), "unknown key");
    return v;
  }
  const json& Require(const json& object, const std::string& key, const std::string& name) const {
    const auto it = object.find(name);
    if (it == object.end()) Fail(Join(key, name), "missing");
    return *it;
  }
  const json* Find(const json& object, const std::string& name) const {
    const auto it = object.find(name);
    return it == object.end() ? nullptr : &*it;
  }
  double Number(const json& v, const std::string& key) const {
    if (!v.is_number()) Fail(key, "must be a number");
    const double x = v.get<double>();
    if (!std::isfinite(x)) Fail(key, "must be finite");
    return x;
  }
  double Positive(const json& v, const std::string& key) const {
    const double x = Number(v, key);
    if (!(x > 0.0)) Fail(key, "must be > 0 (is " + Show(x) + ")");
    return x;
  }
  double NonNegative(const json& v, const std::string& key) const {
    const double x = Number(v, key);
    if (!(x >= 0.0)) Fail(key, "must be >= 0 (is " + Show(x) + ")");
    return x;
  }
  int Integer(const json& v, const std::string& key, int lo, int hi) const {
    if (!v.is_number_integer()) Fail(key, "must be an integer");
    const long long x = v.get<long long>();
    if (x < lo || x > hi)
      Fail(key, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "] (is " +
                    std::to_string(x) + ")");
    return static_cast<int>(x);
  }
  Vec3 Vector3(const json& v, const std::string& key) const {
    if (!v.is_array() || v.size() != 3) Fail(key, "must be an array of 3 numbers");
    Vec3 out;
    for (int i = 0; i < 3; ++i) out[i] = Number(v[i], key + "[" + std::to_string(i) + "]");
    return out;
  }
  std::string String(const json& v, const std::string& key) const {
    if (!v.is_string()) Fail(key, "must be a string");
    return v.get<std::string>();
  }
  bool Bool(const json& v, const std::string& key) const {
    if (!v.is_boolean()) Fail(key, "must be true or false");
    return v.get<bool>();
  }
  const json& Array(const json& v, const std::string& key) const {
    if (!v.is_array()) Fail(key, "must be an array");
    return v;
  }
  static std::string Join(const std::string& key, const std::string& name) {
    return key.empty() ? name : key + "." + name;
  }
  static std::string Index(const std::string& key, size_t i) {
    return key + "[" + std::to_string(i) + "]";
  }

 private:
  std::string path_;
};

// The reader's archive of rodfit/runtime/profile_format.h over one JSON object: each key the
// format declares is read and checked with its dotted path; a key it does not declare is an
// error. Collecting (before reading), it only records the keys declared, so that an unknown key
// is named before any value is read.
class ProfileReader {
 public:
  ProfileReader(const Reader& r, const json& object, std::string key, bool collect = false)
      : r_(r), v_(object), key_(std::move(key)), collect_(collect) {}

  /// Runs `visit(*this)` over the object: first its keys, then their values.
  template <class F>
  void Visit(F visit) {
    if (!v_.is_object()) r_.Fail(key_, "must be an object");
    ProfileReader keys(r_, v_, key_, /*collect=*/true);
    visit(keys);
    for (const auto& item : v_.items())
      if (std::find(keys.declared_.begin(), keys.declared_.end(), item.key()) ==
          keys.declared_.end())
        r_.Fail(Reader::Join(key_, item.key()), "unknown key");
    visit(*this);
  }

  bool reading() const { return !collect_; }

  void Number(const char* key, double* v, profile_format::Bound bound,
              profile_format::Need need = profile_format::kRequired) {
    if (const json* x = Take(key, need)) *v = NumberOf(*x, Path(key), bound);
  }
  void Integer(const char* key, int* v, int lo, int hi) {
    if (const json* x = Take(key, profile_format::kRequired)) *v = r_.Integer(*x, Path(key), lo, hi);
  }
  void Vector(const char* key, Vec3* v, profile_format::Need need = profile_format::kRequired) {
    if (const json* x = Take(key, need)) *v = r_.Vector3(*x, Path(key));
  }
  void Direction(const char* key, Vec3* v) {
    if (const json* x = Take(key, profile_format::kRequired)) *v = DirectionOf(*x, Path(key));
  }
  void OptionalDirection(const char* key, std::optional<Vec3>* v) {
    if (const json* x = Take(key, profile_format::kOptional)) *v = DirectionOf(*x, Path(key));
  }
  void OptionalVector(const char* key, std::optional<Vec3>* v) {
    if (const json* x = Take(key, profile_format::kOptional)) *v = r_.Vector3(*x, Path(key));
  }
  void Text(const char* key, std::string* v,
            profile_format::Need need = profile_format::kRequired) {
    if (const json* x = Take(key, need)) *v = r_.String(*x, Path(key));
  }
  void NumberList(const char* key, std::vector<double>* v) {
    const json* x = Take(key, profile_format::kOptional);
    if (!x) return;
    r_.Array(*x, Path(key));
    v->clear();
    for (size_t i = 0; i < x->size(); ++i)
      v->push_back(r_.Number((*x)[i], Reader::Index(Path(key), i)));
  }
  template <class T, class F>
  void List(const char* key, std::vector<T>* v, F visit) {
    const json* x = Take(key, profile_format::kOptional);
    if (!x) return;
    r_.Array(*x, Path(key));
    for (size_t i = 0; i < x->size(); ++i) {
      T item;
      ProfileReader(r_, (*x)[i], Reader::Index(Path(key), i))
          .Visit([&](ProfileReader& o) { visit(o, item); });
      v->push_back(item);
    }
  }
  template <class F>
  void Object(const char* key, F visit) {
    if (const json* x = Take(key, profile_format::kRequired))
      ProfileReader(r_, *x, Path(key)).Visit(visit);
  }
  template <class T, class F>
  void OptionalObject(const char* key, std::optional<T>* v, F visit) {
    const json* x = Take(key, profile_format::kOptional);
    if (!x) return;
    T item;
    ProfileReader(r_, *x, Path(key)).Visit([&](ProfileReader& o) { visit(o, item); });
    *v = item;
  }
  void Check(bool ok, const char* key, const std::string& message) {
    if (!collect_ && !ok) r_.Fail(Path(key), message);
  }

 private:
  // Declares `key`; reading, its value when present (a required one absent is an error).
  const json* Take(const char* key, profile_format::Need need) {
    declared_.push_back(key);
    if (collect_) return nullptr;
    if (need == profile_format::kRequired) return &r_.Require(v_, key_, key);
    return r_.Find(v_, key);
  }
  std::string Path(const char* key) const { return Reader::Join(key_, key); }
  double NumberOf(const json& x, const std::string& key, profile_format::Bound bound) const {
    switch (bound) {
      case profile_format::kPositive: return r_.Positive(x, key);
      case profile_format::kNonNegative: return r_.NonNegative(x, key);
      case profile_format::kAnyNumber: break;
    }
    return r_.Number(x, key);
  }
  // A direction that must not be zero.
  Vec3 DirectionOf(const json& x, const std::string& key) const {
    const Vec3 d = r_.Vector3(x, key);
    if (!(d.norm() > 0.0)) r_.Fail(key, "must not be zero");
    return d;
  }

  const Reader& r_;
  const json& v_;
  std::string key_;
  bool collect_;
  std::vector<std::string> declared_;
};

// One parameter: its unit must be the table's, its value present (or overridden), finite and
// in range. `zone` marks a spring zone's own parameter (a spring stiffness).
Parameter ReadParameter(const Reader& r, const json& v, const std::string& name, int version,
                        const ProfileReadOptions& options) {
  const std::string key = Reader::Join(pf::kParameters, name);
  r.Object(v, key, std::vector<std::string>(std::begin(pf::kParameterKeys),
                                            std::end(pf::kParameterKeys)));
  Parameter p;
  p.name = name;
  const MaterialParameterInfo* row = FindMaterialParameter(name);
  const std::string unit = p.unit();
  const std::string written = r.String(r.Require(v, key, pf::kUnit), Reader::Join(key, pf::kUnit));
  // Version 1 labelled the damping rows "N/m^2" (the label of spring stiffness); their values
  // were in the table's units all along.
  const bool v1_damping_label = version == 1 && written == "N/m^2" &&
                                std::string(unit).find(" s") != std::string::npos;
  if (written != unit && !v1_damping_label)
    r.Fail(Reader::Join(key, pf::kUnit), "must be \"" + unit + "\" (is \"" + written + "\")");
  if (const json* f = r.Find(v, pf::kFitted)) p.fit = r.Bool(*f, Reader::Join(key, pf::kFitted));
  if (const json* i = r.Find(v, pf::kIdentifiable))
    p.identifiable = r.Bool(*i, Reader::Join(key, pf::kIdentifiable));
  if (const json* t = r.Find(v, pf::kTiedTo)) {
    p.tied_to = r.String(*t, Reader::Join(key, pf::kTiedTo));
    if (!row || !row->tied_to || p.tied_to != row->tied_to)
      r.Fail(Reader::Join(key, pf::kTiedTo), row && row->tied_to
                                   ? "may be tied only to " + std::string(row->tied_to)
                                   : std::string("cannot be tied to another parameter"));
  }
  if (const json* s = r.Find(v, pf::kStd); s && !s->is_null())
    p.std = r.NonNegative(*s, Reader::Join(key, pf::kStd));
  const bool positive = row && row->positive;  // a spring zone's own stiffness may be 0
  auto check = [&](double x, const std::string& where) {
    if (!std::isfinite(x)) r.Fail(where, "must be finite");
    if (positive && !(x > 0.0)) r.Fail(where, "must be > 0 (is " + Show(x) + ")");
    if (!positive && !(x >= 0.0)) r.Fail(where, "must be >= 0 (is " + Show(x) + ")");
  };
  // A row's physical range (material_parameters.h): 1e-300 kg/m is a mistake, not a rod.
  auto in_range = [&](double x, const std::string& note) {
    if (row)
      if (const std::string why = CheckMaterialParameterRange(*row, x, note); !why.empty())
        r.Fail(Reader::Join(key, pf::kValue), why);
  };
  const json& value = r.Require(v, key, pf::kValue);
  const std::string value_key = Reader::Join(key, pf::kValue);
  const auto override_it = options.overrides.find(name);
  if (override_it != options.overrides.end()) {
    check(override_it->second, value_key + " (--set " + name + ")");
    in_range(override_it->second, " (--set " + name + ")");
    p.value = override_it->second;
    p.overridden = true;
    p.tied_to.clear();
    return p;
  }
  if (value.is_null()) {
    r.Fail(value_key,
           std::string("is null (") + (p.identifiable ? "no value" : "not identifiable by the fit") +
               "); rodfit does not invent one: give it with --set " + name + "=VALUE");
  }
  if (!p.identifiable)
    r.Fail(Reader::Join(key, pf::kIdentifiable),
           "is false: the value is not a measurement; give one with --set " + name + "=VALUE");
  p.value = r.Number(value, value_key);
  check(p.value, value_key);
  in_range(p.value, "");
  return p;
}

// `format`, `version`, `rodfit_version`: a rodfit profile of a version this reader reads.
void ReadHeader(const Reader& r, const json& doc, Profile* out) {
  const json& format = r.Require(doc, "", pf::kFormat);
  if (!format.is_string() || format.get<std::string>() != pf::kFormatName)
    r.Fail(pf::kFormat, std::string("must be \"") + pf::kFormatName + "\" (not a rodfit profile)");
  const json& version = r.Require(doc, "", pf::kVersion);
  if (!version.is_number_integer() || version.get<long long>() < kProfileMinVersion ||
      version.get<long long>() > kProfileMaxVersion)
    r.Fail(pf::kVersion, version.dump() + " is not supported (this reader reads " +
                             std::to_string(kProfileMinVersion) + " to " +
                             std::to_string(kProfileMaxVersion) + ")");
  out->version = version.get<int>();
  if (const json* v = r.Find(doc, pf::kRodfitVersion))
    out->rodfit_version = r.String(*v, pf::kRodfitVersion);
}

// `rod`, `gravity` and `held` (a version 1 profile has no held ends: LoadCase's clamp).
void ReadRodAndHeld(const Reader& r, const json& doc, Profile* out) {
  Scene& scene = out->scene;
  ProfileReader(r, r.Require(doc, "", pf::kRod), pf::kRod).Visit([&](ProfileReader& a) {
    pf::VisitRod(a, scene.rod);
  });
  const double length = scene.rod.length;
  if (const json* g = r.Find(doc, pf::kGravity)) scene.gravity = r.Vector3(*g, pf::kGravity);
  if (out->version >= 2) {
    LoadCase held;
    held.name = "profile";
    ProfileReader(r, r.Require(doc, "", pf::kHeld), pf::kHeld).Visit([&](ProfileReader& a) {
      pf::VisitHeld(a, held, length);
    });
    scene.cases.push_back(held);
  } else {
    // Version 1 did not record the held ends: the clamp of LoadCase's defaults.
    scene.cases.push_back(LoadCase());
    scene.cases.back().name = "profile";
    for (const char* key : {pf::kHeld, pf::kSprings, pf::kSection})
      if (r.Find(doc, key)) r.Fail(key, "is a version 2 key (the profile says version 1)");
  }
}

// `springs` and `section`. Returns the zones' own parameters (each must be listed in
// `parameters`).
std::set<std::string> ReadSpringsAndSection(const Reader& r, const json& doc, Profile* out) {
  Scene& scene = out->scene;
  const double length = scene.rod.length;
  std::set<std::string> zone_parameters;
  ProfileReader(r, doc, "").List(pf::kSprings, &scene.springs,
                                 [&](ProfileReader& a, SpringZone& zone) {
                                   pf::VisitSpringZone(a, zone, length);
                                 });
  for (size_t i = 0; i < scene.springs.size(); ++i) {
    const std::string& parameter = scene.springs[i].parameter;
    if (parameter.empty()) continue;
    if (FindMaterialParameter(parameter))
      r.Fail(Reader::Index(pf::kSprings, i) + ".parameter",
             "\"" + parameter + "\" is a material parameter, not a zone's own");
    zone_parameters.insert(parameter);
  }
  ProfileReader(r, doc, "").OptionalObject(pf::kSection, &scene.section,
                                           [](ProfileReader& a, SectionSpec& section) {
                                             pf::VisitSection(a, section);
                                           });
  if (scene.section) {
    std::string why;
    if (!scene.section->Check(&why)) r.Fail(pf::kSection, why);
  }
  return zone_parameters;
}

// `parameters`: every row the model reads (the ring's only with a section) and every zone's
// own, each read by ReadParameter (with the overrides), then set in the material — the rod's
// rows agreeing with `rod`.
void ReadParameters(const Reader& r, const json& doc, const std::set<std::string>& zone_parameters,
                    const ProfileReadOptions& options, Profile* out) {
  Scene& scene = out->scene;
  const json& params = r.Require(doc, "", pf::kParameters);
  if (!params.is_object()) r.Fail(pf::kParameters, "must be an object");
  std::set<std::string> seen;
  for (const auto& item : params.items()) {
    const std::string& name = item.key();
    const MaterialParameterInfo* row = FindMaterialParameter(name);
    // Version 1 wrote zone parameters without their zones: read them as spring stiffnesses.
    if (!row && !zone_parameters.count(name) && out->version >= 2)
      r.Fail(Reader::Join(pf::kParameters, name),
             "unknown parameter (neither in the parameter table nor a spring zone's parameter)");
    if (row && row->needs_section && !scene.section) continue;  // no ring without a section
    out->parameters.push_back(ReadParameter(r, item.value(), name, out->version, options));
    seen.insert(name);
  }
  for (const auto& [name, value] : options.overrides) {
    (void)value;
    if (!seen.count(name))
      r.Fail(Reader::Join(pf::kParameters, name),
             "--set names a parameter the profile does not list");
  }
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (row.required && (!row.needs_section || scene.section) && !seen.count(row.name))
      r.Fail(Reader::Join(pf::kParameters, row.name),
             "missing (" + std::string(row.description) + ")");
  for (const std::string& name : zone_parameters)
    if (!seen.count(name))
      r.Fail(Reader::Join(pf::kParameters, name), "missing (a spring zone's stiffness)");
  for (const Parameter& p : out->parameters) {
    // An isotropic B2 stays tied, so that the rod model sees exactly what the fit's did.
    if (!p.tied_to.empty()) continue;
    const MaterialParameterInfo* row = FindMaterialParameter(p.name);
    if (row && row->rod_field) {
      // A row of the rod (its mass per length, a moving fit's): --set on it sets the rod's; as
      // written it must agree with the rod's block.
      if (!p.overridden && p.value != scene.rod.*(row->rod_field))
        r.Fail(Reader::Join(Reader::Join(pf::kParameters, p.name), pf::kValue),
               "disagrees with rod." + p.name + " (" + Show(scene.rod.*(row->rod_field)) + ")");
    }
    AssignMaterialParameter(p.name, p.value, &scene.material, &scene.rod);
  }
}

}  // namespace

ProfileError::ProfileError(const std::string& file_in, const std::string& key_in,
                           const std::string& message_in)
    : std::runtime_error([&] {
        std::string out = file_in + ": " + (key_in.empty() ? "" : key_in + ": ") + message_in;
        for (char& c : out)
          if (c == '\n' || c == '\r') c = ' ';
        return out;
      }()),
      file(file_in),
      key(key_in),
      message(message_in) {}

const Parameter* Profile::Find(const std::string& name) const {
  for (const Parameter& p : parameters)
    if (p.name == name) return &p;
  return nullptr;
}

// The document's blocks in the order the format lists them (docs/formats.md, "Profile JSON"),
// each read by its function above; an unknown top-level key is named before any value is read.
Profile ParseProfile(const std::string& text, const std::string& path,
                     const ProfileReadOptions& options) {
  const Reader r(path);
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::parse_error& e) {
    r.Fail("", std::string("not a JSON document: ") + e.what());
  }
  r.Object(doc, "", std::vector<std::string>(std::begin(pf::kDocumentKeys),
                                             std::end(pf::kDocumentKeys)));
  Profile out;
  out.path = path;
  ReadHeader(r, doc, &out);
  ReadRodAndHeld(r, doc, &out);
  const std::set<std::string> zone_parameters = ReadSpringsAndSection(r, doc, &out);
  ReadParameters(r, doc, zone_parameters, options, &out);
  if (out.scene.section && !(out.scene.rod.radius > 0.0))
    r.Fail("rod.radius", "must be > 0 with a section");
  return out;
}

Profile LoadProfile(const std::string& path, const ProfileReadOptions& options) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status)) throw ProfileError(path, "", "cannot read the file (missing)");
  if (!fs::is_regular_file(status)) throw ProfileError(path, "", "is not a regular file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) throw ProfileError(path, "", "cannot read the file");
  if (size > kMaxProfileBytes)
    throw ProfileError(path, "", "is larger than the limit of " +
                                     std::to_string(kMaxProfileBytes) + " bytes");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ProfileError(path, "", "cannot read the file");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseProfile(text.str(), path, options);
}

void UseProfileMaterial(const Profile& profile, Scene* scene) {
  const RodSpec& a = profile.scene.rod;
  const RodSpec& b = scene->rod;
  auto differ = [&](const std::string& key, double mine, double theirs) {
    throw ProfileError(profile.path, key, Show(mine) + " differs from the scene's " + Show(theirs) +
                                              " (a profile belongs to its rod)");
  };
  // The rod's numbers went through the JSON text and back: equal to the last bit.
  if (a.length != b.length) differ("rod.length", a.length, b.length);
  if (a.segments != b.segments) differ("rod.segments", a.segments, b.segments);
  if (a.radius != b.radius) differ("rod.radius", a.radius, b.radius);
  // A scene run with a profile may leave its rod's density out: the profile's is used.
  if (std::isnan(b.linear_density)) scene->rod.linear_density = a.linear_density;
  else if (a.linear_density != b.linear_density)
    differ("rod.linear_density", a.linear_density, b.linear_density);
  // The rod's natural shape is the rod's, fitted with it (`rollout --fit rest_curvature`): a
  // scene without one takes the profile's; a scene with another one is another rod.
  if (!a.rest_curvature_s.empty()) {
    if (b.rest_curvature_s.empty()) {
      scene->rod.rest_curvature_s = a.rest_curvature_s;
      scene->rod.rest_curvature_profile = a.rest_curvature_profile;
    } else if (a.rest_curvature_s != b.rest_curvature_s ||
               a.rest_curvature_profile != b.rest_curvature_profile) {
      throw ProfileError(profile.path, Reader::Join(pf::kRod, pf::kRestShape),
                         "differs from the scene's rod.rest_shape (a profile belongs to its rod)");
    }
  }
  for (const SpringZone& zone : scene->springs)
    if (!zone.parameter.empty() && !profile.Find(zone.parameter))
      throw ProfileError(profile.path, Reader::Join(pf::kParameters, zone.parameter),
                         "missing (the scene's spring zone names it)");
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (scene->section && row.needs_section && row.required && !profile.Find(row.name))
      throw ProfileError(profile.path, Reader::Join(pf::kParameters, row.name),
                         "missing (the scene has a section)");
  scene->material = profile.scene.material;
}

bool ParseOverride(const std::string& text, std::map<std::string, double>* overrides,
                   std::string* why) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == text.size()) {
    *why = "expected NAME=VALUE, got \"" + text.substr(0, 80) + "\"";
    return false;
  }
  const std::string name = text.substr(0, eq), number = text.substr(eq + 1);
  char* end = nullptr;
  const double value = std::strtod(number.c_str(), &end);
  if (end != number.c_str() + number.size() || !std::isfinite(value)) {
    *why = name + ": \"" + number.substr(0, 80) + "\" is not a finite number";
    return false;
  }
  (*overrides)[name] = value;
  return true;
}

}  // namespace rodfit
