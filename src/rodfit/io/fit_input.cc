// Observation files to observation models (fit_input.h).
#include "rodfit/io/fit_input.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/image_observations.h"
#include "rodfit/io/sensor_check.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/vision/camera_file.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;

std::vector<double> ColumnOf(const CsvTable& t, const std::string& c) { return t.Column(c); }

// A 3-D point more than this many rod lengths from the case's clamp cannot lie on the rod, even
// as an outlier within its reach: a unit or frame mistake, or a value such as 1e308. Points
// beyond kAbsurdReachLengths are refused first, by their line (millimetres given as metres lie
// about 1000 lengths out and are told as such by CheckSpread).
constexpr double kMaxReachLengths = 100.0;
constexpr double kAbsurdReachLengths = 1e4;

void CheckReach(const CsvTable& t, int row, const Eigen::Vector3d& p, const Vec3& clamp,
                double length, const char* column = "x", double lengths = kMaxReachLengths) {
  const double d = (p - clamp).norm();
  if (!(d <= lengths * length)) {
    char b[160];
    std::snprintf(b, sizeof(b),
                  "the point lies %.3g m from the clamp, more than %.0f rod lengths (%.6g m): "
                  "not on the rod (wrong units or frame?)",
                  d, lengths, length);
    throw InputError(t.name(), t.line(row), column, b);
  }
}

std::string Short(double v) {  // numbers in messages, as a person would type them
  char b[32];
  std::snprintf(b, sizeof(b), "%.10g", v);
  return b;
}

void CheckArcLength(const CsvTable& t, int row, double s, double length) {
  if (!(s >= -1e-12 * length && s <= length * (1 + 1e-12)))
    throw InputError(t.name(), t.line(row), "s",
                     "marker arc length " + Short(s) + " m is outside [0, " + Short(length) + "]");
}

// 3-D observations are in metres. Points spread (bounding-box diagonal) over more than 100 rod
// lengths cannot all lie on the rod, even with outliers inside the rod's reach: almost always
// millimetres written as metres (a spread of ~1000 lengths), caught here rather than as a fit
// that fails or converges to nonsense.
void CheckSpread(const std::string& file, const std::string& what,
                 const std::vector<Eigen::Vector3d>& points, double length) {
  if (points.empty()) return;
  Eigen::Vector3d low = points[0], high = points[0];
  for (const Eigen::Vector3d& p : points) low = low.cwiseMin(p), high = high.cwiseMax(p);
  const double spread = (high - low).norm();
  if (spread > 100.0 * length) {
    char b[96];
    std::snprintf(b, sizeof(b), " spread over %.3g m, %.0f x the rod length ", spread,
                  spread / length);
    throw InputError(file, 0, "",
                     what + b + Short(length) +
                         " m: millimetres given as metres? (x, y, z are in m)");
  }
}

// A haptic log (t, tool position, force on the instrument): the samples where the tool is at
// rest, i.e. its speed (central differences) is below max_speed, thinned evenly to `count`.
struct HapticSample {
  double t;
  Vec3 tool, force;
};

std::vector<HapticSample> QuasiStaticSamples(const ObservationSpec& spec, const Vec3& clamp,
                                             double length) {
  const CsvTable t = CsvTable::Read(spec.file);
  const auto time = t.Column("t"), x = t.Column("tool_x"), y = t.Column("tool_y"),
             z = t.Column("tool_z"), fx = t.Column("fx"), fy = t.Column("fy"), fz = t.Column("fz");
  const int n = t.num_rows();
  if (n < 3) throw InputError(spec.file, 0, "", "a force log needs at least 3 samples");
  // The device's units, frame and sign convention (the entry's unit, force_unit, device_frame,
  // force_on) to the scene's.
  std::vector<Vec3> tool(n), force(n);
  for (int r = 0; r < n; ++r) {
    tool[r] = spec.device_rotation * (spec.position_scale * Vec3(x[r], y[r], z[r])) +
              spec.device_translation;
    force[r] = spec.force_sign * (spec.device_rotation * (spec.force_scale * Vec3(fx[r], fy[r], fz[r])));
  }
  // The instrument holds the rod: a tool position out of its reach is bad data (each quasi-static
  // sample becomes a held point the solve would chase).
  for (int r = 0; r < n; ++r) CheckReach(t, r, tool[r], clamp, length, "tool_x");
  for (int r = 1; r < n; ++r)
    if (!(time[r] > time[r - 1]))
      throw InputError(spec.file, t.line(r), "t",
                       "time must increase strictly (" + FormatDouble(time[r]) + " after " +
                           FormatDouble(time[r - 1]) + ")");
  std::vector<HapticSample> still;
  for (int r = 0; r < n; ++r) {
    const int a = std::max(0, r - 1), b = std::min(n - 1, r + 1);
    const double speed = (tool[b] - tool[a]).norm() / (time[b] - time[a]);  // [m/s]
    if (speed < spec.max_speed) still.push_back({time[r], tool[r], force[r]});
  }
  if (spec.count == 0 && static_cast<int>(still.size()) > kMaxDragSteps)
    throw InputError(spec.file, 0, "",
                     std::to_string(still.size()) + " quasi-static samples, each a case of the "
                     "fit: more than " + std::to_string(kMaxDragSteps) +
                         " (the limit); give the entry a count to thin them");
  if (still.empty())
    throw InputError(spec.file, 0, "max_speed",
                     "no quasi-static sample: the tool never moves slower than " +
                         FormatDouble(spec.max_speed) + " m/s");
  if (spec.count > 0 && static_cast<int>(still.size()) > spec.count) {
    std::vector<HapticSample> thinned;
    for (int k = 0; k < spec.count; ++k)
      thinned.push_back(still[(k * (still.size() - 1)) / std::max(1, spec.count - 1)]);
    still = thinned;
  }
  return still;
}

std::string Label(const ObservationSpec& spec) {
  return spec.type + " " + std::filesystem::path(spec.file).filename().string();
}

}  // namespace

std::vector<FitParameter> FitParametersOf(const Experiment& e) {
  std::vector<FitParameter> out;
  // Every parameter a static fit can see (damping is seen only in motion), then the zones' own.
  std::vector<std::string> names;
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (row.kind != ParameterKind::kDamping) names.push_back(row.name);
  for (const auto& [name, value] : e.scene.material.spring_parameters) names.push_back(name);
  for (const std::string& name : names) {
    const auto it = e.parameters.find(name);
    if (it == e.parameters.end()) {
      // Absent spring_stiffness: no springs (K = 0, held); an absent tied row follows its row.
      const MaterialParameterInfo* row = FindMaterialParameter(name);
      if (row && row->kind == ParameterKind::kSpring) out.push_back({name, 0.0, false, {}, {}});
      continue;
    }
    const ParameterSpec& p = it->second;
    out.push_back({name, p.value, p.fit, p.min, p.max});
  }
  return out;
}

FitOptions FitOptionsOf(const Experiment& e) {
  FitOptions options;
  options.loss = e.fit.loss;
  options.loss_scale = e.fit.loss_scale;
  options.global = e.fit.global;
  options.max_iterations = e.fit.max_iterations;
  options.trusted_sigmas = e.fit.trusted_sigmas;
  return options;
}

// One function, though long: one branch per observation type, each reading its file and
// camera into the case's observation list in the order the YAML lists them.
FitInput BuildFitInput(const Experiment& e) {
  FitInput in;
  in.rod = e.scene.rod;
  in.material = e.scene.material;
  in.gravity = e.scene.gravity;
  in.springs = e.scene.springs;
  in.section = e.scene.section;
  in.parameters = FitParametersOf(e);
  in.statics = e.statics;
  const int nv = e.scene.rod.segments + 1;
  const double L = e.scene.rod.length;
  std::map<std::string, Camera> cameras;
  auto camera = [&](const ObservationSpec& spec) -> const Camera& {
    auto it = cameras.find(CameraKey(spec));
    if (it == cameras.end()) it = cameras.emplace(CameraKey(spec), LoadObservationCamera(spec)).first;
    return it->second;
  };
  // One grasped case per quasi-static haptic sample, appended after the experiment's cases so
  // that input.cases[c] is the experiment's case c for c < its case count.
  std::vector<FitCase> force_cases;
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
      if (spec.type == "grasp_force") {
        for (const HapticSample& h :
             QuasiStaticSamples(spec, e.scene.cases[c].clamp.position, L)) {
          FitCase gc;
          gc.load_case = e.scene.cases[c];
          gc.load_case.name += "@t=" + FormatDouble(h.t);
          gc.load_case.grasp = Grasp{spec.s.at(0), h.tool};
          ForceMeasurement f;
          f.force = h.force;
          f.sigma = spec.sigma;
          f.label = Label(spec) + " t=" + FormatDouble(h.t);
          f.time = h.t;
          f.observation = Label(spec);
          f.type = spec.type;
          gc.grasp_forces.push_back(f);
          force_cases.push_back(std::move(gc));
        }
        continue;
      }
      if (spec.type == "reaction") {  // readings of the force (and moment) on a holder
        const CsvTable t = CsvTable::Read(spec.file);
        const auto fx = ColumnOf(t, "fx"), fy = ColumnOf(t, "fy"), fz = ColumnOf(t, "fz");
        const bool moments = t.HasColumn("mx") || t.HasColumn("my") || t.HasColumn("mz");
        if (moments && !(spec.sigma_moment > 0))
          throw InputError(spec.file, 0, "mx", "moment columns need sigma_moment in the entry");
        std::vector<double> mx, my, mz;
        if (moments) mx = ColumnOf(t, "mx"), my = ColumnOf(t, "my"), mz = ColumnOf(t, "mz");
        if (t.num_rows() == 0) throw InputError(spec.file, 0, "", "no rows");
        for (int r = 0; r < t.num_rows(); ++r) {
          ForceMeasurement f;
          f.force = Vec3(fx[r], fy[r], fz[r]);
          f.sigma = spec.sigma;
          f.point = spec.point;
          f.label = Label(spec) + " row " + std::to_string(r + 1);
          f.observation = Label(spec);
          f.type = spec.type;
          if (moments) {
            f.moment = Vec3(mx[r], my[r], mz[r]);
            f.sigma_moment = spec.sigma_moment;
          }
          fc.grasp_forces.push_back(f);
        }
        continue;
      }
      if (spec.type == "surface_points") {  // fitted against the poke's deformed ring
        const CsvTable t = CsvTable::Read(spec.file);
        const auto x = ColumnOf(t, "x"), y = ColumnOf(t, "y"), z = ColumnOf(t, "z");
        SurfacePoints sp;
        for (int r = 0; r < t.num_rows(); ++r) {
          sp.points.emplace_back(x[r], y[r], z[r]);
          CheckReach(t, r, sp.points.back(), fc.load_case.clamp.position, L);
        }
        if (sp.points.empty()) throw InputError(spec.file, 0, "", "no rows");
        sp.sigma = spec.sigma;
        sp.label = Label(spec);
        fc.surface_points.push_back(std::move(sp));
        continue;
      }
      std::shared_ptr<const Observation> obs;
      try {
        if (spec.type == "markers3d") {
          const CsvTable t = CsvTable::Read(spec.file);
          const auto s = ColumnOf(t, "s"), x = ColumnOf(t, "x"), y = ColumnOf(t, "y"),
                     z = ColumnOf(t, "z");
          std::vector<Marker3d> markers;
          std::vector<Eigen::Vector3d> positions;
          for (int r = 0; r < t.num_rows(); ++r) {
            CheckArcLength(t, r, s[r], L);
            markers.push_back({std::min(std::max(s[r], 0.0), L), Vec3(x[r], y[r], z[r])});
            positions.emplace_back(x[r], y[r], z[r]);
          }
          if (markers.empty()) throw InputError(spec.file, 0, "", "no rows");
          // An absurd point by its line, then millimetres as metres (the likelier mistake), then
          // any single point too far.
          for (int r = 0; r < t.num_rows(); ++r)
            CheckReach(t, r, positions[r], fc.load_case.clamp.position, L, "x", kAbsurdReachLengths);
          CheckSpread(spec.file, "the markers", positions, L);
          for (int r = 0; r < t.num_rows(); ++r)
            CheckReach(t, r, positions[r], fc.load_case.clamp.position, L);
          obs = std::make_shared<Markers3dObservation>(arc, markers, spec.sigma);
        } else if (spec.type == "points3d") {
          const CsvTable t = CsvTable::Read(spec.file);
          const auto x = ColumnOf(t, "x"), y = ColumnOf(t, "y"), z = ColumnOf(t, "z");
          std::vector<Eigen::Vector3d> pts;
          for (int r = 0; r < t.num_rows(); ++r) pts.emplace_back(x[r], y[r], z[r]);
          if (pts.empty()) throw InputError(spec.file, 0, "", "no rows");
          for (int r = 0; r < t.num_rows(); ++r)
            CheckReach(t, r, pts[r], fc.load_case.clamp.position, L, "x", kAbsurdReachLengths);
          CheckSpread(spec.file, "the points", pts, L);
          for (int r = 0; r < t.num_rows(); ++r)
            CheckReach(t, r, pts[r], fc.load_case.clamp.position, L);
          obs = std::make_shared<Points3dObservation>(nv, pts, spec.sigma);
        } else if (spec.type == "image_points") {
          const CsvTable t = CsvTable::Read(spec.file);
          const Camera& cam = camera(spec);
          const auto u = ColumnOf(t, "u"), v = ColumnOf(t, "v");
          if (t.num_rows() == 0) throw InputError(spec.file, 0, "", "no rows");
          if (t.HasColumn("s")) {
            const auto s = ColumnOf(t, "s");
            std::vector<MarkerPixel> px;
            for (int r = 0; r < t.num_rows(); ++r) {
              CheckArcLength(t, r, s[r], L);
              CheckOnSensor(t, r, Eigen::Vector2d(u[r], v[r]), cam, spec.camera);
              px.push_back({std::min(std::max(s[r], 0.0), L), Eigen::Vector2d(u[r], v[r])});
            }
            obs = std::make_shared<ImageMarkersObservation>(arc, cam, px, spec.sigma);
          } else {
            std::vector<Eigen::Vector2d> px;
            for (int r = 0; r < t.num_rows(); ++r) {
              px.emplace_back(u[r], v[r]);
              CheckOnSensor(t, r, px.back(), cam, spec.camera);
            }
            obs = std::make_shared<ImageCurveObservation>(nv, cam, px, spec.sigma);
          }
        } else if (spec.type == "images") {
          const Camera& cam = camera(spec);
          const std::vector<Eigen::Vector2d> px = ImagePointsFromImage(spec, cam, fc.load_case);
          obs = std::make_shared<ImageCurveObservation>(nv, cam, px, spec.sigma);
        } else {
          throw InputError(e.path, spec.line, "type", "unknown observation type " + spec.type);
        }
      } catch (const std::invalid_argument& err) {
        // The observation models' own checks (a non-finite value, a camera failing its check).
        throw InputError(spec.file, 0, spec.type, err.what());
      }
      fc.observations.push_back(obs);
      fc.labels.push_back(Label(spec));
    }
    in.cases.push_back(std::move(fc));
  }
  for (FitCase& gc : force_cases) in.cases.push_back(std::move(gc));
  return in;
}

void CheckCamerasSeeTheStart(const Experiment& e) {
  const Scene& scene = e.scene;
  std::optional<CaseSolution> previous;
  std::map<std::string, Camera> cameras;
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
      auto it = cameras.find(CameraKey(spec));
      if (it == cameras.end())
        it = cameras.emplace(CameraKey(spec), LoadObservationCamera(spec)).first;
      const Camera& cam = it->second;
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
      const std::string where = "case " + scene.cases[c].name + ", " + spec.type + " " +
                                fs::path(spec.file).filename().string() + ": ";
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
