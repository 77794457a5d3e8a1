// Profile JSON (profile.h).
#include "rodfit/io/profile.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/version.h"

namespace rodfit {
namespace {

const char* LossName(RobustLoss l) {
  switch (l) {
    case RobustLoss::kNone: return "none";
    case RobustLoss::kHuber: return "huber";
    case RobustLoss::kCauchy: return "cauchy";
    case RobustLoss::kSoftL1: return "soft_l1";
  }
  return "none";
}

nlohmann::json Vec(const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

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

nlohmann::json ProfileJson(const Experiment& e, const FitOptions& options, const FitResult& r) {
  using nlohmann::json;
  json p;
  p["format"] = "rodfit-profile";
  p["version"] = 1;
  p["rodfit_version"] = RODFIT_VERSION;
  const RodSpec& rod = e.scene.rod;
  p["rod"] = {{"length", rod.length},
              {"segments", rod.segments},
              {"radius", rod.radius},
              {"linear_density", rod.linear_density},
              {"rest_curvature", Vec(rod.rest_curvature)}};
  p["gravity"] = Vec(e.scene.gravity);
  json params = json::object();
  for (const ParameterEstimate& est : r.parameters) {
    // A parameter the data do not determine has no value: where the fit stopped (often a bound)
    // would be imported as if measured. Its start is kept apart, under "start".
    const bool determined = !est.fitted || est.identifiable;
    json q = {{"value", determined ? json(est.value) : json(nullptr)},
              {"std", est.std ? json(*est.std) : json(nullptr)},
              {"fitted", est.fitted},
              {"unit", est.unit}};
    if (est.fitted) {
      q["start"] = est.start;
      q["identifiable"] = est.identifiable;
      if (!est.identifiable) q["reason"] = est.reason;
      if (est.at_bound) q["at_bound"] = true;
    }
    params[est.name] = q;
  }
  if (!params.contains("bend_stiffness_2") && params.contains("bend_stiffness")) {
    // Absent in the experiment: isotropic, tied to bend_stiffness (docs/model.md, "Stiffnesses").
    json q = params["bend_stiffness"];
    q["fitted"] = false;
    q["tied_to"] = "bend_stiffness";
    q.erase("start");
    q.erase("identifiable");
    q.erase("reason");
    q.erase("at_bound");
    params["bend_stiffness_2"] = q;
  }
  p["parameters"] = params;
  json fit;
  fit["success"] = r.success;
  fit["termination"] = r.message;
  fit["iterations"] = r.iterations;
  fit["global_evaluations"] = r.global_evaluations;
  fit["initial_cost"] = r.initial_cost;
  fit["final_cost"] = r.final_cost;
  fit["num_residuals"] = r.num_residuals;
  fit["residual_variance"] = r.residual_variance;
  fit["sigmas_trusted"] = options.trusted_sigmas;
  fit["loss"] = LossName(options.loss);
  fit["loss_scale"] = options.loss_scale;
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
    rms.push_back(entry);
  }
  fit["rms"] = rms;
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
  p["fit"] = fit;
  return p;
}

std::string FormatProfile(const nlohmann::json& profile) { return profile.dump(2) + "\n"; }

void WriteProfile(const std::string& path, const nlohmann::json& profile) {
  WriteFileAtomically(path, FormatProfile(profile));
}

}  // namespace rodfit
