// Identification of the cross-section ring's stiffness from `surface_points`: the
// surface residuals' Jacobian against central differences of the forward map, recovery of
// ring_bend_stiffness from noisy points around the dent, and the refused combinations.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "rodfit/fit/fit.h"
#include "rodfit/solve/poke.h"
#include "rodfit/solve/statics.h"

namespace rodfit {
namespace {

// A bowel segment on its mesentery with the cross-section model (data/scenes/bowel_poke.yaml).
FitInput PokedBowel() {
  FitInput in;
  in.rod.length = 0.15;
  in.rod.segments = 30;
  in.rod.radius = 0.012;
  in.rod.linear_density = 0.45;
  in.material.bend_stiffness = 2e-4;
  in.material.twist_stiffness = 1.5e-4;
  in.material.stretch_stiffness = 40;
  in.material.spring_stiffness = 300;
  in.material.ring_bend_stiffness = 2e-5;
  in.material.ring_stretch_stiffness = 5.0;
  in.springs = {{0.0, 0.15, ""}};
  SectionSpec section;
  section.radius = 0.012;
  section.nodes = 32;
  in.section = section;
  return in;
}

LoadCase PokeCase(const std::string& name, const Vec3& force) {
  LoadCase c;
  c.name = name;
  c.clamp.tangent = Vec3(1, 0, 0);
  c.clamp.normal = Vec3(0, 0, 1);
  c.poke = Poke{0.075, force};
  return c;
}

// Points on the true deformed ring, a fraction along each edge, plus Gaussian noise.
std::shared_ptr<const SurfacePointSet> Surface(const FitInput& in, const LoadCase& c,
                                               double sigma, double noise, std::mt19937* rng) {
  const RodModel model(in.rod, in.material, in.gravity, c, in.springs);
  RodState state = model.StraightState();
  EXPECT_TRUE(SolveStatics(model, StaticsOptions(), &state).converged);
  const PokeResult poke =
      SolvePoke(model, state, *in.section,
                {in.material.ring_bend_stiffness, in.material.ring_stretch_stiffness});
  EXPECT_TRUE(poke.ring.summary.converged);
  std::normal_distribution<double> N(0.0, 1.0);
  std::vector<Vec3> points;
  const int n = static_cast<int>(poke.deformed_world.cols());
  for (int k = 0; k < n; ++k) {
    const Vec3 a = poke.deformed_world.col(k), b = poke.deformed_world.col((k + 1) % n);
    Vec3 p = a + 0.37 * (b - a);
    if (noise > 0) p += noise * Vec3(N(*rng), N(*rng), N(*rng));
    points.push_back(p);
  }
  return std::make_shared<SurfacePointSet>("surface_points", "surface_points " + c.name, points,
                                           sigma);
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
  add("ring_bend_stiffness", in->material.ring_bend_stiffness);
  add("ring_stretch_stiffness", in->material.ring_stretch_stiffness);
}

const Parameter& Get(const FitResult& r, const std::string& name) {
  for (const auto& p : r.parameters)
    if (p.name == name) return p;
  throw std::runtime_error(name);
}

TEST(RingFit, SurfaceJacobianMatchesCentralDifferences) {
  FitInput in = PokedBowel();
  std::mt19937 rng(3);
  for (const Vec3& f : {Vec3(0, -0.02, 0), Vec3(0, 0.01, -0.015)}) {
    FitCase fc;
    fc.load_case = PokeCase("poke", f);
    fc.measurements.push_back(Surface(in, fc.load_case, 1e-4, 3e-4, &rng));
    in.cases.push_back(fc);
  }
  AddParameters(&in, {"ring_bend_stiffness", "ring_stretch_stiffness"}, 1.0);
  // Off the truth, so that the residuals are not small.
  const std::vector<double> logp = {std::log(3e-5), std::log(3.0)};
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  ASSERT_TRUE(EvaluateForwardMap(in, logp, &r, &J));
  ASSERT_EQ(r.size(), 2 * 3 * 32);
  ASSERT_EQ(J.cols(), 2);
  for (int c = 0; c < 2; ++c) {
    const double h = 1e-6;
    std::vector<double> lp = logp, lm = logp;
    lp[c] += h;
    lm[c] -= h;
    Eigen::VectorXd rp, rm;
    ASSERT_TRUE(EvaluateForwardMap(in, lp, &rp, nullptr));
    ASSERT_TRUE(EvaluateForwardMap(in, lm, &rm, nullptr));
    const Eigen::VectorXd fd = (rp - rm) / (2 * h);
    EXPECT_GT(J.col(c).norm(), 1e-3) << "column " << c;
    EXPECT_LT((J.col(c) - fd).norm(), 1e-5 * J.col(c).norm() + 1e-7) << "column " << c;
  }
}

TEST(RingFit, RecoversRingBendStiffnessFromNoisySurfacePoints) {
  FitInput in = PokedBowel();
  std::mt19937 rng(11);
  const double sigma = 3e-5;  // [m] a laser profilometer's noise
  for (const Vec3& f : {Vec3(0, -0.03, 0), Vec3(0, 0.015, -0.02)}) {
    FitCase fc;
    fc.load_case = PokeCase("poke", f);
    fc.measurements.push_back(Surface(in, fc.load_case, sigma, sigma, &rng));
    in.cases.push_back(fc);
  }
  AddParameters(&in, {"ring_bend_stiffness"}, 3.0);
  FitOptions options;
  const FitResult result = Fit(in, options);
  ASSERT_TRUE(result.success) << result.message;
  const Parameter& kb = Get(result, "ring_bend_stiffness");
  ASSERT_TRUE(kb.std.has_value()) << kb.reason;
  EXPECT_STREQ(kb.unit(), "N m^2");
  EXPECT_LT(std::abs(kb.value - 2e-5), 3 * *kb.std) << kb.value << " +- " << *kb.std;
  EXPECT_LT(*kb.std, 0.1 * 2e-5);
  EXPECT_NEAR(result.residual_variance, 1.0, 0.5);
  EXPECT_DOUBLE_EQ(Get(result, "ring_stretch_stiffness").value, 5.0);  // held
  int surfaces = 0;
  for (const ObservationFit& o : result.observations) {
    if (o.type != "surface_points") continue;
    ++surfaces;
    EXPECT_EQ(o.num_measurements, 32);
    EXPECT_GT(o.rms, 0.3 * sigma);
    EXPECT_LT(o.rms, 3.0 * sigma);  // [m]
  }
  EXPECT_EQ(surfaces, 2);
}

TEST(RingFit, RefusesRodParametersWithSurfacePoints) {
  FitInput in = PokedBowel();
  std::mt19937 rng(5);
  FitCase fc;
  fc.load_case = PokeCase("poke", Vec3(0, -0.02, 0));
  fc.measurements.push_back(Surface(in, fc.load_case, 1e-4, 0.0, &rng));
  in.cases.push_back(fc);
  AddParameters(&in, {"ring_bend_stiffness", "spring_stiffness"}, 1.0);
  try {
    Fit(in, FitOptions());
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("surface_points constrain the ring's stiffness only"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("spring_stiffness"), std::string::npos) << e.what();
  }
  Eigen::VectorXd r;
  EXPECT_THROW(EvaluateForwardMap(in, {0.0, 0.0}, &r, nullptr), std::invalid_argument);
}

TEST(RingFit, RefusesRingParameterWithoutSurfacePoints) {
  FitInput in = PokedBowel();
  FitCase fc;
  fc.load_case = PokeCase("poke", Vec3(0, -0.02, 0));
  const RodModel model(in.rod, in.material, in.gravity, fc.load_case, in.springs);
  std::vector<Marker3d> markers = {{0.15, Vec3(0.15, 0, 0)}, {0.1, Vec3(0.1, 0, 0)}};
  fc.measurements.push_back(MakeShapeMeasurement(
      "markers3d", "markers3d", Markers3dObservation(VertexArcLengths(model), markers, 1e-3)));
  in.cases.push_back(fc);
  AddParameters(&in, {"ring_stretch_stiffness"}, 1.0);
  try {
    Fit(in, FitOptions());
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ring_stretch_stiffness"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("surface_points"), std::string::npos) << e.what();
  }
}

TEST(RingFit, RefusesSurfacePointsWithoutPokeOrSection) {
  FitInput in = PokedBowel();
  std::mt19937 rng(5);
  FitCase fc;
  fc.load_case = PokeCase("poke", Vec3(0, -0.02, 0));
  fc.measurements.push_back(Surface(in, fc.load_case, 1e-4, 0.0, &rng));
  fc.load_case.poke.reset();
  in.cases.push_back(fc);
  AddParameters(&in, {"ring_bend_stiffness"}, 1.0);
  EXPECT_THROW(Fit(in, FitOptions()), std::invalid_argument);
  in.cases[0].load_case.poke = Poke{0.075, Vec3(0, -0.02, 0)};
  in.section.reset();
  EXPECT_THROW(Fit(in, FitOptions()), std::invalid_argument);
}

// The report's section plot reads FitResult::rest_sections / sections: the poked ring at rest
// and deformed at the fitted parameters. Fitted to noise-free points on the true ring, the
// fitted ring passes through them, and it differs from the rest ring by the dent.
TEST(RingFit, FittedSectionIsRecordedPerCase) {
  FitInput in = PokedBowel();
  std::mt19937 rng(4);
  for (const Vec3& f : {Vec3(0, -0.03, 0), Vec3(0, 0.015, -0.02)}) {
    FitCase fc;
    fc.load_case = PokeCase("poke", f);
    fc.measurements.push_back(Surface(in, fc.load_case, 3e-5, 0.0, &rng));
    in.cases.push_back(fc);
  }
  AddParameters(&in, {"ring_bend_stiffness"}, 3.0);
  const FitResult result = Fit(in, FitOptions());
  ASSERT_TRUE(result.success) << result.message;
  ASSERT_EQ(result.shapes.size(), in.cases.size());
  ASSERT_EQ(result.sections.size(), in.cases.size());
  ASSERT_EQ(result.rest_sections.size(), in.cases.size());
  for (size_t c = 0; c < in.cases.size(); ++c) {
    const Eigen::Matrix3Xd& ring = result.sections[c];
    const Eigen::Matrix3Xd& rest = result.rest_sections[c];
    ASSERT_EQ(ring.cols(), in.section->nodes);
    ASSERT_EQ(rest.cols(), in.section->nodes);
    Eigen::Matrix3Xd closed(3, ring.cols() + 1);
    closed << ring, ring.col(0);
    double worst = 0.0;
    const auto& set = dynamic_cast<const SurfacePointSet&>(*in.cases[c].measurements[0]);
    for (const Vec3& q : set.points()) {
      const PolylineFoot foot = ClosestPointOnPolyline<3>(closed, q);
      worst = std::max(worst, std::sqrt(foot.distance_squared));
    }
    EXPECT_LT(worst, 1e-7) << "case " << c;  // [m]: 1/300 of the 30 um sigma
    EXPECT_GT((ring - rest).colwise().norm().maxCoeff(), 1e-4) << "case " << c;  // the dent [m]
  }
}

}  // namespace
}  // namespace rodfit
