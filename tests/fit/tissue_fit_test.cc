// Identification of the tissue terms: a single spring stiffness and two zone
// stiffnesses from markers, K from a haptic force log alone, and the force Jacobian against
// central differences of the forward map.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "rodfit/fit/fit.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics.h"

namespace rodfit {
namespace {

// A bowel-like segment, 0.15 m, tied to the mesentery in two zones.
FitInput Bowel() {
  FitInput in;
  in.rod.length = 0.15;
  in.rod.segments = 40;
  in.rod.radius = 0.012;
  in.rod.linear_density = 0.45;
  in.material.bend_stiffness = 2e-4;
  in.material.twist_stiffness = 1.5e-4;
  in.material.stretch_stiffness = 40;
  in.material.spring_stiffness = 150;
  in.material.spring_parameters["mesentery"] = 400;
  in.springs = {{0.0, 0.07, ""}, {0.07, 0.15, "mesentery"}};
  return in;
}

LoadCase Case(const std::string& name) {
  LoadCase c;
  c.name = name;
  c.clamp.tangent = Vec3(1, 0, 0);
  c.clamp.normal = Vec3(0, 0, 1);
  return c;
}

RodState Solve(const FitInput& in, const LoadCase& c, RodModel** keep = nullptr) {
  static thread_local std::unique_ptr<RodModel> model;
  model = std::make_unique<RodModel>(in.rod, in.material, in.gravity, c, in.springs);
  RodState state = model->StraightState();
  const StaticsSummary s = SolveStatics(*model, StaticsOptions(), &state);
  EXPECT_TRUE(s.converged) << s.BriefReport();
  if (keep) *keep = model.get();
  return state;
}

std::shared_ptr<const Measurement> Markers(const FitInput& in, const Mat3X& x, double sigma,
                                           double noise, std::mt19937* rng) {
  std::normal_distribution<double> N(0.0, 1.0);
  const RodModel model(in.rod, in.material, in.gravity, Case("m"), in.springs);
  std::vector<Marker3d> markers;
  for (int i = 4; i <= in.rod.segments; i += 4) {
    Vec3 p = x.col(i);
    if (noise > 0) p += noise * Vec3(N(*rng), N(*rng), N(*rng));
    markers.push_back({model.arc_length(i), p});
  }
  return MakeShapeMeasurement("markers3d", "markers3d",
                              Markers3dObservation(VertexArcLengths(model), markers, sigma));
}

void AddParameters(FitInput* in, const std::vector<std::string>& fitted, double factor) {
  auto add = [&](const std::string& name, double v) {
    const bool fit = std::find(fitted.begin(), fitted.end(), name) != fitted.end();
    in->parameters.push_back({name, fit ? v * factor : v, fit, {}, {}});
  };
  add("bend_stiffness", in->material.bend_stiffness);
  add("twist_stiffness", in->material.twist_stiffness);
  add("stretch_stiffness", in->material.stretch_stiffness);
  add("spring_stiffness", in->material.spring_stiffness);
  add("mesentery", in->material.spring_parameters.at("mesentery"));
}

const Parameter& Get(const FitResult& r, const std::string& name) {
  for (const auto& p : r.parameters)
    if (p.name == name) return p;
  throw std::runtime_error(name);
}

// Grasp cases: the instrument lifts and pulls s = 0.1 to several positions.
std::vector<LoadCase> GraspCases() {
  std::vector<LoadCase> out;
  const Vec3 targets[] = {{0.1, 0.0, 0.01}, {0.1, 0.01, 0.015}, {0.105, -0.01, 0.02},
                          {0.095, 0.0, 0.025}};
  for (int k = 0; k < 4; ++k) {
    LoadCase c = Case("grasp" + std::to_string(k));
    c.grasp = Grasp{0.1, targets[k]};
    out.push_back(c);
  }
  return out;
}

TEST(TissueFit, SingleSpringStiffnessFromMarkers) {
  FitInput in = Bowel();
  in.springs = {{0.0, 0.15, ""}};
  in.material.spring_parameters.clear();
  std::mt19937 rng(1);
  for (const LoadCase& c : {Case("rest"), GraspCases()[0]}) {
    FitCase fc;
    fc.load_case = c;
    fc.measurements.push_back(Markers(in, Solve(in, c).x, 2e-4, 2e-4, &rng));
    in.cases.push_back(fc);
  }
  auto add = [&](const std::string& name, double v, bool fit) {
    in.parameters.push_back({name, fit ? 3 * v : v, fit, {}, {}});
  };
  add("bend_stiffness", 2e-4, false);
  add("twist_stiffness", 1.5e-4, false);
  add("stretch_stiffness", 40, false);
  add("spring_stiffness", 150, true);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  const Parameter& k = Get(r, "spring_stiffness");
  ASSERT_TRUE(k.std.has_value()) << k.reason;
  EXPECT_LT(std::abs(k.value - 150), 3 * *k.std) << k.value << " +- " << *k.std;
}

TEST(TissueFit, TwoZoneStiffnessesFromMarkers) {
  FitInput in = Bowel();
  std::mt19937 rng(2);
  for (const LoadCase& c : {Case("rest"), GraspCases()[0], GraspCases()[2]}) {
    FitCase fc;
    fc.load_case = c;
    fc.measurements.push_back(Markers(in, Solve(in, c).x, 2e-4, 2e-4, &rng));
    in.cases.push_back(fc);
  }
  AddParameters(&in, {"spring_stiffness", "mesentery"}, 0.4);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  for (const auto& [name, truth] :
       std::vector<std::pair<std::string, double>>{{"spring_stiffness", 150}, {"mesentery", 400}}) {
    const Parameter& k = Get(r, name);
    ASSERT_TRUE(k.std.has_value()) << name << ": " << k.reason;
    EXPECT_LT(std::abs(k.value - truth), 3 * *k.std) << name << " " << k.value << " +- " << *k.std;
    EXPECT_STREQ(k.unit(), "N/m^2");
  }
}

// Force residuals: each quasi-static sample of a haptic log is a grasped case.
FitInput ForceOnly(double noise, std::mt19937* rng) {
  FitInput in = Bowel();
  std::normal_distribution<double> N(0.0, 1.0);
  for (const LoadCase& c : GraspCases()) {
    RodModel* model = nullptr;
    const RodState state = Solve(in, c, &model);
    FitCase fc;
    fc.load_case = c;
    Vec3 f = GraspReaction(*model, state);
    if (noise > 0) f += noise * Vec3(N(*rng), N(*rng), N(*rng));
    ForceMeasurement m;
    m.force = f;
    m.sigma = 0.01;
    m.label = "grasp_force log " + c.name;
    fc.measurements.push_back(std::make_shared<ForceReadings>(
        "grasp_force", m.label, std::vector<ForceMeasurement>{m}));
    in.cases.push_back(fc);
  }
  return in;
}

TEST(TissueFit, ForceJacobianMatchesCentralDifferences) {
  std::mt19937 rng(3);
  FitInput in = ForceOnly(0.0, &rng);
  AddParameters(&in, {"spring_stiffness", "mesentery", "stretch_stiffness"}, 1.3);
  std::vector<double> lp;
  for (const auto& p : in.parameters)
    if (p.fit) lp.push_back(std::log(p.value));
  VecX r;
  Eigen::MatrixXd J;
  ASSERT_TRUE(EvaluateForwardMap(in, lp, &r, &J));
  for (size_t k = 0; k < lp.size(); ++k) {
    const double h = 1e-4;
    std::vector<double> a = lp, b = lp;
    a[k] += h;
    b[k] -= h;
    VecX ra, rb;
    ASSERT_TRUE(EvaluateForwardMap(in, a, &ra, nullptr));
    ASSERT_TRUE(EvaluateForwardMap(in, b, &rb, nullptr));
    const VecX fd = (ra - rb) / (2 * h);
    EXPECT_LT((J.col(k) - fd).cwiseAbs().maxCoeff(), 1e-5 * fd.cwiseAbs().maxCoeff() + 1e-9)
        << k << "\nIFT " << J.col(k).transpose() << "\ncentral " << fd.transpose();
  }
}

TEST(TissueFit, SpringStiffnessFromAForceLogAlone) {
  std::mt19937 rng(4);
  FitInput in = ForceOnly(0.01, &rng);
  AddParameters(&in, {"spring_stiffness", "mesentery"}, 2.5);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  for (const auto& [name, truth] :
       std::vector<std::pair<std::string, double>>{{"spring_stiffness", 150}, {"mesentery", 400}}) {
    const Parameter& k = Get(r, name);
    ASSERT_TRUE(k.std.has_value()) << name << ": " << k.reason;
    EXPECT_LT(std::abs(k.value - truth), 3 * *k.std) << name << " " << k.value << " +- " << *k.std;
  }
  bool has_force_rms = false;
  for (const ObservationFit& o : r.observations) has_force_rms |= o.type == "grasp_force";
  EXPECT_TRUE(has_force_rms);
}

}  // namespace
}  // namespace rodfit
