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

namespace rodfit {
namespace {

using nlohmann::json;

// Below this sine of the angle between a clamp's tangent and normal the frame is taken to be a
// mistake (the scene reader's limit).
constexpr double kMinClampSine = 1e-3;
constexpr int kMaxProfileSegments = 100000;  // the scene reader's rod.segments limit
constexpr int kMaxProfileSectionNodes = 256;

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

// A direction that must not be zero.
Vec3 Direction(const Reader& r, const json& v, const std::string& key) {
  const Vec3 d = r.Vector3(v, key);
  if (!(d.norm() > 0.0)) r.Fail(key, "must not be zero");
  return d;
}

void CheckFrame(const Reader& r, const Vec3& tangent, const Vec3& normal, const std::string& key) {
  if (tangent.cross(normal).norm() < kMinClampSine * tangent.norm() * normal.norm())
    r.Fail(key, "is (nearly) parallel to the tangent");
}

RodSpec ReadRod(const Reader& r, const json& v) {
  r.Object(v, "rod", {"length", "segments", "radius", "linear_density", "rest_curvature",
                      "vertex_s"});
  RodSpec rod;
  rod.length = r.Positive(r.Require(v, "rod", "length"), "rod.length");
  rod.segments = r.Integer(r.Require(v, "rod", "segments"), "rod.segments", 2, kMaxProfileSegments);
  rod.radius = r.NonNegative(r.Require(v, "rod", "radius"), "rod.radius");
  // 0: the fit had no radius (a version 1 profile may say so); any other value is a real one.
  if (rod.radius != 0.0)
    if (const std::string why = CheckRodRadius(rod.radius, rod.length); !why.empty())
      r.Fail("rod.radius", why);
  rod.linear_density = r.NonNegative(r.Require(v, "rod", "linear_density"), "rod.linear_density");
  if (const json* k = r.Find(v, "rest_curvature"))
    rod.rest_curvature = r.Vector3(*k, "rod.rest_curvature");
  if (const json* s = r.Find(v, "vertex_s")) {
    r.Array(*s, "rod.vertex_s");
    if (static_cast<int>(s->size()) != rod.segments + 1)
      r.Fail("rod.vertex_s", "must have segments + 1 = " + std::to_string(rod.segments + 1) +
                                 " values (has " + std::to_string(s->size()) + ")");
    for (size_t i = 0; i < s->size(); ++i) {
      const double x = r.Number((*s)[i], Reader::Index("rod.vertex_s", i));
      if (i == 0 ? x != 0.0 : !(x > rod.vertex_s.back()))
        r.Fail(Reader::Index("rod.vertex_s", i), "must increase strictly from 0");
      rod.vertex_s.push_back(x);
    }
    if (std::abs(rod.vertex_s.back() - rod.length) > 1e-12 * rod.length)
      r.Fail("rod.vertex_s", "must end at rod.length (" + Show(rod.length) + ")");
  }
  return rod;
}

// An arc length s in [lo, hi] of the rod.
double ArcLength(const Reader& r, const json& v, const std::string& key, double length) {
  const double s = r.Number(v, key);
  if (!(s >= 0.0 && s <= length))
    r.Fail(key, "must lie in [0, rod.length = " + Show(length) + "] (is " + Show(s) + ")");
  return s;
}

Interval ReadInterval(const Reader& r, const json& v, const std::string& key, double length,
                      std::string* parameter) {
  std::vector<std::string> allowed = {"from", "to"};
  if (parameter) allowed.push_back("parameter");
  r.Object(v, key, allowed);
  Interval in;
  in.from = ArcLength(r, r.Require(v, key, "from"), key + ".from", length);
  in.to = ArcLength(r, r.Require(v, key, "to"), key + ".to", length);
  if (!(in.from < in.to)) r.Fail(key + ".to", "must be greater than from (" + Show(in.from) + ")");
  if (parameter) {
    if (const json* p = r.Find(v, "parameter")) *parameter = r.String(*p, key + ".parameter");
  }
  return in;
}

LoadCase ReadHeld(const Reader& r, const json& v, double length) {
  r.Object(v, "held", {"case", "clamp", "end_clamp", "end_pin", "pins", "cuts"});
  LoadCase c;
  c.name = "profile";
  if (const json* name = r.Find(v, "case")) c.name = r.String(*name, "held.case");
  const json& clamp = r.Require(v, "held", "clamp");
  r.Object(clamp, "held.clamp", {"position", "tangent", "normal"});
  c.clamp.position = r.Vector3(r.Require(clamp, "held.clamp", "position"), "held.clamp.position");
  c.clamp.tangent = Direction(r, r.Require(clamp, "held.clamp", "tangent"), "held.clamp.tangent");
  c.clamp.normal = Direction(r, r.Require(clamp, "held.clamp", "normal"), "held.clamp.normal");
  CheckFrame(r, c.clamp.tangent, c.clamp.normal, "held.clamp.normal");
  if (const json* end = r.Find(v, "end_clamp")) {
    r.Object(*end, "held.end_clamp", {"position", "tangent", "normal"});
    EndClamp e;
    e.position = r.Vector3(r.Require(*end, "held.end_clamp", "position"), "held.end_clamp.position");
    e.tangent =
        Direction(r, r.Require(*end, "held.end_clamp", "tangent"), "held.end_clamp.tangent");
    if (const json* n = r.Find(*end, "normal")) {
      e.normal = Direction(r, *n, "held.end_clamp.normal");
      CheckFrame(r, e.tangent, *e.normal, "held.end_clamp.normal");
    }
    c.end_clamp = e;
  }
  if (const json* pin = r.Find(v, "end_pin")) {
    if (c.end_clamp) r.Fail("held.end_pin", "a rod has an end clamp or an end pin, not both");
    c.end_pin = r.Vector3(*pin, "held.end_pin");
  }
  if (const json* pins = r.Find(v, "pins")) {
    r.Array(*pins, "held.pins");
    for (size_t i = 0; i < pins->size(); ++i) {
      const std::string key = Reader::Index("held.pins", i);
      r.Object((*pins)[i], key, {"s", "position"});
      Pin pin;
      pin.s = ArcLength(r, r.Require((*pins)[i], key, "s"), key + ".s", length);
      if (!(pin.s > 0.0 && pin.s < length)) r.Fail(key + ".s", "must lie inside (0, rod.length)");
      pin.position = r.Vector3(r.Require((*pins)[i], key, "position"), key + ".position");
      c.pins.push_back(pin);
    }
  }
  if (const json* cuts = r.Find(v, "cuts")) {
    r.Array(*cuts, "held.cuts");
    for (size_t i = 0; i < cuts->size(); ++i)
      c.cuts.push_back(ReadInterval(r, (*cuts)[i], Reader::Index("held.cuts", i), length, nullptr));
  }
  return c;
}

SectionSpec ReadSection(const Reader& r, const json& v) {
  r.Object(v, "section", {"radius", "nodes", "h_factor", "stop_factor"});
  SectionSpec s;
  s.radius = r.Positive(r.Require(v, "section", "radius"), "section.radius");
  s.nodes = r.Integer(r.Require(v, "section", "nodes"), "section.nodes", 8, kMaxProfileSectionNodes);
  if (const json* h = r.Find(v, "h_factor")) s.h_factor = r.Positive(*h, "section.h_factor");
  if (const json* f = r.Find(v, "stop_factor")) s.stop_factor = r.Positive(*f, "section.stop_factor");
  std::string why;
  if (!s.Check(&why)) r.Fail("section", why);
  return s;
}

// One parameter: its unit must be the table's, its value present (or overridden), finite and
// in range. `zone` marks a spring zone's own parameter (a spring stiffness).
Parameter ReadParameter(const Reader& r, const json& v, const std::string& name, int version,
                        const ProfileReadOptions& options) {
  const std::string key = "parameters." + name;
  r.Object(v, key, {"value", "std", "fitted", "identifiable", "unit", "start", "reason",
                    "at_bound", "tied_to"});
  Parameter p;
  p.name = name;
  const MaterialParameterInfo* row = FindMaterialParameter(name);
  const std::string unit = p.unit();
  const std::string written = r.String(r.Require(v, key, "unit"), key + ".unit");
  // Version 1 labelled the damping rows "N/m^2" (the label of spring stiffness); their values
  // were in the table's units all along.
  const bool v1_damping_label = version == 1 && written == "N/m^2" &&
                                std::string(unit).find(" s") != std::string::npos;
  if (written != unit && !v1_damping_label)
    r.Fail(key + ".unit", "must be \"" + unit + "\" (is \"" + written + "\")");
  if (const json* f = r.Find(v, "fitted")) p.fit = r.Bool(*f, key + ".fitted");
  if (const json* i = r.Find(v, "identifiable")) p.identifiable = r.Bool(*i, key + ".identifiable");
  if (const json* t = r.Find(v, "tied_to")) {
    p.tied_to = r.String(*t, key + ".tied_to");
    if (!row || !row->tied_to || p.tied_to != row->tied_to)
      r.Fail(key + ".tied_to", row && row->tied_to
                                   ? "may be tied only to " + std::string(row->tied_to)
                                   : std::string("cannot be tied to another parameter"));
  }
  if (const json* s = r.Find(v, "std"); s && !s->is_null())
    p.std = r.NonNegative(*s, key + ".std");
  const bool positive = row && row->positive;  // a spring zone's own stiffness may be 0
  auto check = [&](double x, const std::string& where) {
    if (!std::isfinite(x)) r.Fail(where, "must be finite");
    if (positive && !(x > 0.0)) r.Fail(where, "must be > 0 (is " + Show(x) + ")");
    if (!positive && !(x >= 0.0)) r.Fail(where, "must be >= 0 (is " + Show(x) + ")");
  };
  const json& value = r.Require(v, key, "value");
  const auto override_it = options.overrides.find(name);
  if (override_it != options.overrides.end()) {
    check(override_it->second, key + ".value (--set " + name + ")");
    p.value = override_it->second;
    p.overridden = true;
    p.tied_to.clear();
    return p;
  }
  if (value.is_null()) {
    r.Fail(key + ".value",
           std::string("is null (") + (p.identifiable ? "no value" : "not identifiable by the fit") +
               "); rodfit does not invent one: give it with --set " + name + "=VALUE");
  }
  if (!p.identifiable)
    r.Fail(key + ".identifiable", "is false: the value is not a measurement; give one with --set " +
                                      name + "=VALUE");
  p.value = r.Number(value, key + ".value");
  check(p.value, key + ".value");
  return p;
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

Profile ParseProfile(const std::string& text, const std::string& path,
                     const ProfileReadOptions& options) {
  const Reader r(path);
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::parse_error& e) {
    r.Fail("", std::string("not a JSON document: ") + e.what());
  }
  r.Object(doc, "", {"format", "version", "rodfit_version", "rod", "gravity", "held", "springs",
                     "section", "parameters", "derived", "fit"});
  const json& format = r.Require(doc, "", "format");
  if (!format.is_string() || format.get<std::string>() != "rodfit-profile")
    r.Fail("format", "must be \"rodfit-profile\" (not a rodfit profile)");
  Profile out;
  out.path = path;
  const json& version = r.Require(doc, "", "version");
  if (!version.is_number_integer() || version.get<long long>() < kProfileMinVersion ||
      version.get<long long>() > kProfileMaxVersion)
    r.Fail("version", version.dump() + " is not supported (this reader reads " +
                          std::to_string(kProfileMinVersion) + " to " +
                          std::to_string(kProfileMaxVersion) + ")");
  out.version = version.get<int>();
  if (const json* v = r.Find(doc, "rodfit_version"))
    out.rodfit_version = r.String(*v, "rodfit_version");
  Scene& scene = out.scene;
  scene.rod = ReadRod(r, r.Require(doc, "", "rod"));
  const double length = scene.rod.length;
  if (const json* g = r.Find(doc, "gravity")) scene.gravity = r.Vector3(*g, "gravity");
  if (out.version >= 2) {
    scene.cases.push_back(ReadHeld(r, r.Require(doc, "", "held"), length));
  } else {
    // Version 1 did not record the held ends: the clamp of LoadCase's defaults.
    scene.cases.push_back(LoadCase());
    scene.cases.back().name = "profile";
    for (const char* key : {"held", "springs", "section"})
      if (r.Find(doc, key)) r.Fail(key, "is a version 2 key (the profile says version 1)");
  }
  std::set<std::string> zone_parameters;
  if (const json* springs = r.Find(doc, "springs")) {
    r.Array(*springs, "springs");
    for (size_t i = 0; i < springs->size(); ++i) {
      SpringZone zone;
      const Interval in =
          ReadInterval(r, (*springs)[i], Reader::Index("springs", i), length, &zone.parameter);
      zone.from = in.from;
      zone.to = in.to;
      if (!zone.parameter.empty()) {
        if (FindMaterialParameter(zone.parameter))
          r.Fail(Reader::Index("springs", i) + ".parameter",
                 "\"" + zone.parameter + "\" is a material parameter, not a zone's own");
        zone_parameters.insert(zone.parameter);
      }
      scene.springs.push_back(zone);
    }
  }
  if (const json* section = r.Find(doc, "section")) scene.section = ReadSection(r, *section);

  const json& params = r.Require(doc, "", "parameters");
  if (!params.is_object()) r.Fail("parameters", "must be an object");
  std::set<std::string> seen;
  for (const auto& item : params.items()) {
    const std::string& name = item.key();
    const MaterialParameterInfo* row = FindMaterialParameter(name);
    // Version 1 wrote zone parameters without their zones: read them as spring stiffnesses.
    if (!row && !zone_parameters.count(name) && out.version >= 2)
      r.Fail("parameters." + name, "unknown parameter (neither in the parameter table nor a "
                                   "spring zone's parameter)");
    if (row && row->needs_section && !scene.section) continue;  // no ring without a section
    out.parameters.push_back(ReadParameter(r, item.value(), name, out.version, options));
    seen.insert(name);
  }
  for (const auto& [name, value] : options.overrides) {
    (void)value;
    if (!seen.count(name))
      r.Fail("parameters." + name, "--set names a parameter the profile does not list");
  }
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (row.required && (!row.needs_section || scene.section) && !seen.count(row.name))
      r.Fail(std::string("parameters.") + row.name, "missing (" + std::string(row.description) + ")");
  for (const std::string& name : zone_parameters)
    if (!seen.count(name)) r.Fail("parameters." + name, "missing (a spring zone's stiffness)");
  for (const Parameter& p : out.parameters) {
    // An isotropic B2 stays tied, so that the rod model sees exactly what the fit's did.
    if (!p.tied_to.empty()) continue;
    const MaterialParameterInfo* row = FindMaterialParameter(p.name);
    if (row && row->rod_field) {
      // A row of the rod (its mass per length, a moving fit's): --set on it sets the rod's; as
      // written it must agree with the rod's block.
      if (!p.overridden && p.value != scene.rod.*(row->rod_field))
        r.Fail("parameters." + p.name + ".value",
               "disagrees with rod." + p.name + " (" + Show(scene.rod.*(row->rod_field)) + ")");
    }
    AssignMaterialParameter(p.name, p.value, &scene.material, &scene.rod);
  }
  if (scene.section && !(scene.rod.radius > 0.0))
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
  for (const SpringZone& zone : scene->springs)
    if (!zone.parameter.empty() && !profile.Find(zone.parameter))
      throw ProfileError(profile.path, "parameters." + zone.parameter,
                         "missing (the scene's spring zone names it)");
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (scene->section && row.needs_section && row.required && !profile.Find(row.name))
      throw ProfileError(profile.path, std::string("parameters.") + row.name,
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
