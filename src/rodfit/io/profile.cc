// Profile JSON (profile.h).
#include "rodfit/io/profile.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/settings.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/runtime/profile_format.h"
#include "rodfit/version.h"

namespace rodfit {
namespace {


namespace pf = profile_format;

nlohmann::json Vec(const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

// The writer's archive of rodfit/runtime/profile_format.h: each key the format declares, with
// its value, into one JSON object (an optional one only when it holds a value).
class ProfileWriter {
 public:
  explicit ProfileWriter(nlohmann::json* object) : v_(*object) {}

  bool reading() const { return false; }
  void Number(const char* key, double* v, pf::Bound, pf::Need = pf::kRequired) { v_[key] = *v; }
  void Integer(const char* key, int* v, int, int) { v_[key] = *v; }
  void Vector(const char* key, Vec3* v, pf::Need = pf::kRequired) { v_[key] = Vec(*v); }
  void Direction(const char* key, Vec3* v) { v_[key] = Vec(*v); }
  void OptionalDirection(const char* key, std::optional<Vec3>* v) {
    if (*v) v_[key] = Vec(**v);
  }
  void OptionalVector(const char* key, std::optional<Vec3>* v) {
    if (*v) v_[key] = Vec(**v);
  }
  void Text(const char* key, std::string* v, pf::Need need = pf::kRequired) {
    if (need == pf::kRequired || !v->empty()) v_[key] = *v;
  }
  void NumberList(const char* key, std::vector<double>* v) {
    if (!v->empty()) v_[key] = *v;
  }
  template <class T, class F>
  void List(const char* key, std::vector<T>* v, F visit) {
    nlohmann::json list = nlohmann::json::array();
    for (T& item : *v) {
      nlohmann::json object = nlohmann::json::object();
      ProfileWriter o(&object);
      visit(o, item);
      list.push_back(object);
    }
    v_[key] = list;
  }
  template <class F>
  void Object(const char* key, F visit) {
    nlohmann::json object = nlohmann::json::object();
    ProfileWriter o(&object);
    visit(o);
    v_[key] = object;
  }
  template <class T, class F>
  void OptionalObject(const char* key, std::optional<T>* v, F visit) {
    if (*v) Object(key, [&](ProfileWriter& o) { visit(o, **v); });
  }
  void Check(bool, const char*, const std::string&) {}

 private:
  nlohmann::json& v_;
};

// Engineering constants of a solid round section (DeriveRoundSection), or null with the reason
// when a stiffness they need is not determined.
nlohmann::json DerivedJson(const Material& m, const RodSpec& rod,
                           const std::set<std::string>& undetermined) {
  using nlohmann::json;
  json derived;
  // The rod's density row, when a fit left it undetermined, leaves the mass density unknown.
  bool density_known = rod.radius > 0.0;
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (row.rod_field == &RodSpec::linear_density && undetermined.count(row.name))
      density_known = false;
  derived["mass_density"] = density_known
                                ? json(rod.linear_density / (M_PI * rod.radius * rod.radius))
                                : json(nullptr);
  for (const MaterialParameterInfo& row : MaterialParameters()) {
    if (row.kind != ParameterKind::kRodStiffness) continue;
    const std::string name = row.name;
    if (undetermined.count(name) || !(rod.radius > 0.0)) {
      derived["round_section"] = nullptr;
      derived["round_section_missing"] =
          rod.radius > 0.0 ? name + " is not determined" : "the rod has no radius";
      return derived;
    }
  }
  const RoundSectionConstants c = DeriveRoundSection(m, rod.radius);
  json round = {{"radius", c.radius},
                {"youngs_modulus", c.youngs_modulus},
                {"youngs_modulus_stretch", c.youngs_modulus_stretch},
                {"shear_modulus", c.shear_modulus},
                {"poisson_ratio", c.poisson_ratio},
                {"consistent", c.consistent}};
  if (!c.consistent) round["inconsistency"] = c.inconsistency;
  derived["round_section"] = round;
  return derived;
}

}  // namespace

std::string FileDigest(const std::string& path) {
  CheckInputFile(path, "an input file");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path, 0, "", "cannot read the file");
  std::uint64_t h = 1469598103934665603ULL;
  char buf[65536];
  while (f.read(buf, sizeof(buf)) || f.gcount() > 0) {
    for (std::streamsize i = 0; i < f.gcount(); ++i) {
      h ^= static_cast<unsigned char>(buf[i]);
      h *= 1099511628211ULL;
    }
  }
  char out[17];
  std::snprintf(out, sizeof(out), "%016llx", static_cast<unsigned long long>(h));
  return out;
}

namespace {

// The fit's settings that the profile carries (SettingsArchive::Carry), each written under its
// profile key: a word as its word, a number as its number.
class CarriedSettingsWriter final : public SettingsArchive {
 public:
  explicit CarriedSettingsWriter(nlohmann::json* object) : v_(*object) {}

  bool reading() const override { return false; }
  void Carry(const char* key, const char* profile_key) override {
    key_ = key;
    profile_key_ = profile_key;
  }
  void Integer(const char* key, int* value, int, int) override { Write(key, *value); }
  void Count(const char* key, int* value, int, int) override { Write(key, *value); }
  void Number(const char* key, double* value, double, double) override { Write(key, *value); }
  void Positive(const char* key, double* value) override { Write(key, *value); }
  void Bool(const char* key, bool* value) override { Write(key, *value); }
  void Choice(const char* key, int* index, const std::vector<std::string>& words,
              const std::string&) override {
    Write(key, words[*index]);
  }
  void Require(const char*) override {}
  bool Has(const char*) const override { return true; }
  void Check(bool, const char*, const std::string&) override {}

 private:
  // Writes the visited key when the declaration right before it carried it.
  void Write(const char* key, const nlohmann::json& value) {
    if (key_ == key) v_[profile_key_] = value;
    key_.clear();
  }

  nlohmann::json& v_;
  std::string key_, profile_key_;
};

// The profile's `fit` object: the fit's summary, its correlations, per entry its rms, per case
// its nuisances, and a digest of every input file.
nlohmann::json FitJson(const Experiment& e, const FitOptions& options, const FitResult& r,
                       const ResidualCheck& check) {
  using nlohmann::json;
  json fit;
  fit["success"] = r.success;
  fit["termination"] = r.message;
  fit["iterations"] = r.iterations;
  fit["global_evaluations"] = r.global_evaluations;
  fit["initial_cost"] = r.initial_cost;
  fit["final_cost"] = r.final_cost;
  fit["num_residuals"] = r.num_residuals;
  fit["residual_variance"] = r.residual_variance;
  fit["residual_variance_band"] = {check.band.low, check.band.high};
  fit["residuals_explained"] = !check.above;
  // The settings the profile carries, as Serialize(FitOptions) declares them.
  FitOptions settings = options;
  CarriedSettingsWriter carried(&fit);
  Serialize(&carried, &settings);
  fit["correlation"] = {{"parameters", r.fitted_names}, {"matrix", json::array()}};
  for (int i = 0; i < r.correlation.rows(); ++i) {
    json row = json::array();
    for (int j = 0; j < r.correlation.cols(); ++j)
      row.push_back(std::isfinite(r.correlation(i, j)) ? json(r.correlation(i, j)) : json(nullptr));
    fit["correlation"]["matrix"].push_back(row);
  }
  json rms = json::array();
  for (const ObservationFit& o : r.observations) {
    json entry = {{"case", o.case_name},  {"observation", o.label}, {"type", o.type},
                  {"count", o.num_measurements}, {"rms", o.rms}, {"unit", o.unit}};
    if (std::isfinite(o.rms_moment)) {
      entry["rms_moment"] = o.rms_moment;
      entry["unit_moment"] = "N m";
    }
    if (std::isfinite(o.rms_roll)) {
      entry["rms_roll"] = o.rms_roll;
      entry["unit_roll"] = "deg";
    }
    if (!o.warning.empty()) entry["warning"] = o.warning;
    rms.push_back(entry);
  }
  fit["rms"] = rms;
  // The cases' nuisances (fitted held frames, points, gravity): per case, never part of the
  // material. Keys carry the unit: rotation_deg / std_deg / prior_deg, offset_m / std_m / prior_m.
  if (!r.nuisances.empty()) {
    json cases = json::array();
    for (const NuisanceEstimate& n : r.nuisances) {
      json value = json::array(), std_dev = json::array();
      for (int i = 0; i < 3; ++i) {
        value.push_back(n.value[i]);
        std_dev.push_back(std::isfinite(n.std[i]) ? json(n.std[i]) : json(nullptr));
      }
      cases.push_back({{"case", n.case_name}, {"held", n.held},
                       {n.quantity + "_" + n.unit, value}, {"std_" + n.unit, std_dev},
                       {"prior_" + n.unit, n.prior}});
    }
    fit["cases"] = cases;
  }
  // Digest of every input file: the experiment, the data files and the cameras.
  json inputs = json::array();
  std::set<std::string> seen;
  auto add = [&](const std::string& path) {
    if (path.empty() || !seen.insert(path).second) return;
    inputs.push_back({{"file", std::filesystem::path(path).lexically_normal().string()},
                      {"fnv1a64", FileDigest(path)}});
  };
  add(e.path);
  for (const CaseSpec& c : e.cases)
    for (const ObservationSpec& o : c.observations) {
      add(o.file);
      add(o.camera);
    }
  fit["inputs"] = inputs;
  return fit;
}

}  // namespace

// The profile's keys in the order docs/formats.md lists them, so that the code reads as the
// format (the `fit` object in FitJson).
nlohmann::json ProfileJson(const Experiment& e, const FitOptions& options, const FitResult& r,
                           const ResidualCheck& check) {
  using nlohmann::json;
  json p;
  p[pf::kFormat] = pf::kFormatName;
  p[pf::kVersion] = kProfileVersion;
  p[pf::kRodfitVersion] = RODFIT_VERSION;
  const Scene& scene = e.scene;
  ProfileWriter doc(&p);
  // The rod as fitted: a moving experiment may fit a row of the rod, its linear density (a
  // parameter the data do not determine keeps its start here, and its row says it is not a
  // measurement).
  RodSpec rod = scene.rod;
  for (const Parameter& est : r.parameters) {
    const MaterialParameterInfo* row = FindMaterialParameter(est.name);
    if (row && row->rod_field && (!est.fit || est.identifiable)) rod.*(row->rod_field) = est.value;
  }
  doc.Object(pf::kRod, [&](ProfileWriter& a) { pf::VisitRod(a, rod); });
  p[pf::kGravity] = Vec(scene.gravity);
  // The held boundary of the rod as mounted: the first case's clamp, end clamp or end pin,
  // interior pins and cuts. An instrument's grasp or poke is the simulator's tool, not the rod's.
  if (!scene.cases.empty()) {
    LoadCase held = scene.cases.front();
    doc.Object(pf::kHeld, [&](ProfileWriter& a) { pf::VisitHeld(a, held, rod.length); });
  }
  std::vector<SpringZone> springs = scene.springs;
  doc.List(pf::kSprings, &springs,
           [&](ProfileWriter& a, SpringZone& zone) { pf::VisitSpringZone(a, zone, rod.length); });
  std::optional<SectionSpec> section = scene.section;
  doc.OptionalObject(pf::kSection, &section,
                     [](ProfileWriter& a, SectionSpec& s) { pf::VisitSection(a, s); });

  // The material as fitted: a parameter the data do not determine has no value.
  Material fitted = scene.material;
  std::set<std::string> undetermined;
  json params = json::object();
  std::set<std::string> listed;
  for (const Parameter& est : r.parameters) {
    // A parameter the data do not determine has no value: where the fit stopped (often a bound)
    // would be imported as if measured. Its start is kept apart, under "start".
    const bool determined = !est.fit || est.identifiable;
    json q = {{pf::kValue, determined ? json(est.value) : json(nullptr)},
              {pf::kStd, est.std ? json(*est.std) : json(nullptr)},
              {pf::kFitted, est.fit},
              {pf::kIdentifiable, determined},
              {pf::kUnit, est.unit()}};
    if (est.fit) {
      q[pf::kStart] = est.start;
      if (!est.identifiable) q[pf::kReason] = est.reason;
      if (est.at_bound) q[pf::kAtBound] = true;
    }
    params[est.name] = q;
    listed.insert(est.name);
    const MaterialParameterInfo* row = FindMaterialParameter(est.name);
    if (row && row->rod_field) {
      if (!determined) undetermined.insert(est.name);  // the rod's: set above
    } else if (determined) {
      // A tied row (bend_stiffness_2 absent) is listed at its row's value but stays tied.
      if (!row || !row->tied_to || MaterialParameterValue(scene.material, est.name) || est.fit)
        AssignMaterialParameter(est.name, est.value, &fitted);
    } else {
      undetermined.insert(est.name);
    }
  }
  for (const MaterialParameterInfo& row : MaterialParameters()) {
    if (!row.tied_to || params.contains(row.name) || !params.contains(row.tied_to)) continue;
    // Absent in the experiment: tied (isotropic, docs/model.md, "Stiffnesses").
    json q = params[row.tied_to];
    q[pf::kFitted] = false;
    q[pf::kTiedTo] = row.tied_to;
    q.erase(pf::kStart);
    q.erase(pf::kReason);
    q.erase(pf::kAtBound);
    params[row.name] = q;
    listed.insert(row.name);
    if (undetermined.count(row.tied_to)) undetermined.insert(row.name);
  }
  // Every other row of the parameter table the model reads, at the scene's value: a simulator
  // gets damping and the rest explicitly rather than by a default of its own. A row of the rod
  // (its density) is in `rod`, and listed here only when a fit estimated it.
  for (const MaterialParameterInfo& row : MaterialParameters()) {
    if (listed.count(row.name) || (row.needs_section && !scene.section) || row.rod_field)
      continue;
    const std::optional<double> v = MaterialParameterValue(scene.material, row.name);
    if (!v) continue;
    params[row.name] = {{pf::kValue, *v}, {pf::kStd, nullptr}, {pf::kFitted, false},
                        {pf::kIdentifiable, true}, {pf::kUnit, row.unit}};
  }
  p[pf::kParameters] = params;
  p[pf::kDerived] = DerivedJson(fitted, rod, undetermined);
  p[pf::kFit] = FitJson(e, options, r, check);
  return p;
}

std::string FormatProfile(const nlohmann::json& profile) { return profile.dump(2) + "\n"; }

void WriteProfile(const std::string& path, const nlohmann::json& profile) {
  WriteFileAtomically(path, FormatProfile(profile));
}

}  // namespace rodfit
