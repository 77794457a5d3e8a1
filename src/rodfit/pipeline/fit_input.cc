// An experiment's observation entries to the fit's measurements, by their kinds (fit_input.h).
#include "rodfit/pipeline/fit_input.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <optional>

#include "rodfit/io/csv.h"  // ParseDouble
#include "rodfit/io/errors.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/pipeline/observation_kind.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/vision/camera_file.h"

namespace rodfit {

std::string DisplayCaseName(const std::string& name) {
  const size_t at = name.rfind("@t=");
  if (at == std::string::npos) return name;
  double t = 0.0;
  if (!ParseDouble(name.substr(at + 3), &t)) return name;
  char b[32];
  std::snprintf(b, sizeof(b), "%.6g", t);
  return name.substr(0, at + 3) + b;
}

std::vector<Parameter> FitParametersOf(const Experiment& e) {
  std::vector<Parameter> out;
  // Every parameter a static fit can see (damping and mass are seen only in motion), then the
  // zones' own.
  std::vector<std::string> names;
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (row.kind != ParameterKind::kDamping && row.kind != ParameterKind::kMass)
      names.push_back(row.name);
  for (const auto& [name, value] : e.scene.material.spring_parameters) names.push_back(name);
  for (const std::string& name : names) {
    const auto it = e.parameters.find(name);
    if (it == e.parameters.end()) {
      // Absent spring_stiffness: no springs (K = 0, held); an absent tied row follows its row.
      const MaterialParameterInfo* row = FindMaterialParameter(name);
      if (row && row->kind == ParameterKind::kSpring) out.push_back({name, 0.0, false, {}, {}});
      continue;
    }
    out.push_back(it->second);
  }
  return out;
}

FitOptions FitOptionsOf(const Experiment& e) { return e.fit; }

FitInput BuildFitInput(const Experiment& e) {
  FitInput in;
  in.rod = e.scene.rod;
  in.material = e.scene.material;
  in.gravity = e.scene.gravity;
  in.gravity_prior_deg = e.scene.gravity_prior_deg;
  in.springs = e.scene.springs;
  in.section = e.scene.section;
  in.parameters = FitParametersOf(e);
  in.statics = e.statics;
  CameraCache cameras;
  // Cases of their own that a kind makes (one grasped case per quasi-static haptic sample),
  // appended after the experiment's cases so that input.cases[c] is the experiment's case c for
  // c < its case count.
  std::vector<FitCase> more_cases;
  for (size_t c = 0; c < e.scene.cases.size(); ++c) {
    FitCase fc;
    fc.load_case = e.scene.cases[c];
    // The fit solves a symmetric case as the whole rod: its observations and reactions lie on
    // both halves, and the sensitivities and reaction derivatives are the whole rod's (the
    // half's mirrored ones are not derived). The solution is the same (tests/solve/symmetry_test).
    fc.load_case.symmetry.reset();
    // The case's own vertex arc lengths: held points move the vertex nearest to them.
    std::vector<double> arc;
    try {
      arc = VertexArcLengths(RodModel(e.scene.rod, e.scene.material, e.scene.gravity,
                                      fc.load_case, e.scene.springs));
    } catch (const std::invalid_argument& err) {
      throw InputError(e.path, e.cases[c].line, "cases[" + std::to_string(c) + "]", err.what());
    }
    for (const ObservationSpec& spec : e.cases[c].observations) {
      const KindContext context(e, static_cast<int>(c), spec, fc.load_case, arc, &cameras);
      try {
        KindOf(spec).build(context, &fc, &more_cases);
      } catch (const std::invalid_argument& err) {
        // The measurement models' own checks (a non-finite value, a camera failing its check).
        throw InputError(spec.file, 0, spec.type, err.what());
      }
    }
    // Residual order within a case (the RMS table's and residuals.csv's): its centre-line
    // observations, then its force readings, then its surface points, each in file order.
    auto group = [](const std::shared_ptr<const Measurement>& m) {
      return m->needs_section() ? 2 : m->needs_reactions() ? 1 : 0;
    };
    std::stable_sort(fc.measurements.begin(), fc.measurements.end(),
                     [&](const auto& a, const auto& b) { return group(a) < group(b); });
    in.cases.push_back(std::move(fc));
  }
  for (FitCase& gc : more_cases) in.cases.push_back(std::move(gc));
  return in;
}

void CheckCamerasSeeTheStart(const Experiment& e) {
  const Scene& scene = e.scene;
  std::optional<CaseSolution> previous;
  CameraCache cameras;
  for (size_t c = 0; c < scene.cases.size(); ++c) {
    bool seen = false;
    for (const ObservationSpec& spec : e.cases[c].observations) seen |= !spec.camera.empty();
    // A later case may start from this one (`start: previous`): solve it when one does.
    const bool next_needs = c + 1 < scene.cases.size() &&
                            scene.cases[c + 1].start.kind == StartShape::Kind::kPrevious;
    if (!seen && !next_needs) {
      previous.reset();
      continue;
    }
    std::optional<CaseSolution> solved;
    try {
      solved = SolveCase(scene, static_cast<int>(c), previous ? &*previous : nullptr, e.statics);
    } catch (const std::exception&) {
    }
    previous = solved;
    if (!seen || !solved || !solved->summary.converged) continue;  // the fit reports it
    const Mat3X& x = solved->shape;
    for (const ObservationSpec& spec : e.cases[c].observations) {
      if (spec.camera.empty()) continue;
      const Camera& cam = cameras.Get(spec);
      int behind = 0, inside = 0;
      for (int k = 0; k < x.cols(); ++k) {
        const Eigen::Vector3d p = x.col(k);
        const Eigen::Vector3d p_cam = cam.cam_from_world_R * p + cam.cam_from_world_t;
        if (!(p_cam.z() > kMinProjectionDepth)) {
          ++behind;
          continue;
        }
        Eigen::Vector2d uv;
        if (Project(cam, p, &uv) && cam.InImage(uv)) ++inside;
      }
      const std::string where = "case " + scene.cases[c].name + ", " + EntryLabel(spec) + ": ";
      if (behind == x.cols())
        throw InputError(spec.camera, 0, "",
                         where + "the rod at the start values lies behind this camera (all " +
                             std::to_string(behind) + " vertices): a wrong pose (rvec/tvec of "
                             "world-to-camera, or inverted)?");
      if (inside == 0)
        throw InputError(spec.camera, 0, "",
                         where + "the rod at the start values projects entirely outside the " +
                             std::to_string(cam.K.width) + "x" + std::to_string(cam.K.height) +
                             " image: the camera looks elsewhere (a wrong pose?), or its "
                             "distortion is wrong");
    }
  }
}

}  // namespace rodfit
