// Identification tests: the forward map's Jacobian against central differences,
// parameter recovery on synthetic experiments (noise-free within 0.5 %, noisy within 3 std),
// calibrated uncertainty over seeds, identifiability verdicts and bad requests.
#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rodfit/fit/fit.h"
#include "rodfit/solve/statics.h"

namespace rodfit {
namespace {

// A nylon-like suture, 0.2 m, 40 segments.
FitInput Suture(int segments = 40) {
  FitInput in;
  in.rod.length = 0.2;
  in.rod.segments = segments;
  in.rod.radius = 1.25e-4;
  in.rod.linear_density = 5.6e-5;
  in.material.bend_stiffness = 1.0e-6;
  in.material.twist_stiffness = 8.0e-7;
  in.material.stretch_stiffness = 245;
  in.gravity = Vec3(0, 0, -9.81);
  return in;
}

LoadCase Clamped(const std::string& name, const Vec3& tangent, const Vec3& normal) {
  LoadCase c;
  c.name = name;
  c.clamp.tangent = tangent;
  c.clamp.normal = normal;
  return c;
}

Mat3X Solve(const FitInput& in, const LoadCase& c) {
  const RodModel model(in.rod, in.material, in.gravity, c);
  RodState state = model.StraightState();
  const StaticsSummary s = SolveStatics(model, StaticsOptions(), &state);
  EXPECT_TRUE(s.converged) << s.BriefReport();
  return state.x;
}

// Markers at `count` evenly spaced s in (0, L], Gaussian noise sigma (0 = exact).
std::shared_ptr<const Measurement> Markers(const FitInput& in, const Mat3X& x, int count,
                                           double sigma, double noise, std::mt19937* rng) {
  std::normal_distribution<double> N(0.0, 1.0);
  const RodModel model(in.rod, in.material, in.gravity, LoadCase());
  std::vector<Marker3d> markers;
  const double l = in.rod.length / in.rod.segments;
  for (int k = 1; k <= count; ++k) {
    Marker3d m;
    m.s = in.rod.length * k / count;
    const double u = m.s / l;
    const int e = std::min(static_cast<int>(u), in.rod.segments - 1);
    const double a = u - e;
    m.p_world = (1 - a) * x.col(e) + a * x.col(e + 1);
    if (noise > 0) m.p_world += noise * Vec3(N(*rng), N(*rng), N(*rng));
    markers.push_back(m);
  }
  return MakeShapeMeasurement("markers3d", "markers3d",
                              Markers3dObservation(VertexArcLengths(model), markers, sigma));
}

void AddParameters(FitInput* in, const std::vector<std::string>& fitted, double start_factor) {
  const Material& m = in->material;
  auto add = [&](const std::string& name, double v) {
    Parameter p;
    p.name = name;
    p.fit = std::find(fitted.begin(), fitted.end(), name) != fitted.end();
    p.value = p.fit ? v * start_factor : v;
    in->parameters.push_back(p);
  };
  add("bend_stiffness", m.bend_stiffness);
  if (m.bend_stiffness_2) add("bend_stiffness_2", *m.bend_stiffness_2);
  add("twist_stiffness", m.twist_stiffness);
  add("stretch_stiffness", m.stretch_stiffness);
}

const Parameter& Estimate(const FitResult& r, const std::string& name) {
  for (const auto& p : r.parameters)
    if (p.name == name) return p;
  throw std::runtime_error("no parameter " + name);
}

// The 4-orientation cantilever protocol: horizontal, 30 degrees up, rolled 90 degrees (so
// gravity bends it about the other axis), and with a sideways tip pull.
FitInput Protocol(const FitInput& truth_material, double noise, std::mt19937* rng,
                  int markers = 10, double sigma = 3e-4) {
  FitInput in = truth_material;
  std::vector<LoadCase> cases = {
      Clamped("flat", Vec3(1, 0, 0), Vec3(0, 0, 1)),
      Clamped("up30", Vec3(std::cos(0.5), 0, std::sin(0.5)), Vec3(0, 0, 1)),
      Clamped("rolled", Vec3(1, 0, 0), Vec3(0, 1, 0)),
      Clamped("pulled", Vec3(1, 0, 0.2), Vec3(0, 0, 1)),
  };
  cases[3].tip_force = Vec3(0, 3e-5, 0);
  for (const LoadCase& c : cases) {
    FitCase fc;
    fc.load_case = c;
    fc.measurements.push_back(Markers(in, Solve(in, c), markers, sigma, noise, rng));
    in.cases.push_back(fc);
  }
  return in;
}

TEST(Fit, JacobianMatchesCentralDifferencesOfTheForwardMap) {
  FitInput truth = Suture(30);
  truth.material.bend_stiffness_2 = 1.6e-6;
  std::mt19937 rng(1);
  FitInput in = Protocol(truth, 0.0, &rng);
  in.cases[3].load_case.tip_moment = Vec3(2e-6, 0, 1e-6);  // twist coupling for GJ
  AddParameters(&in, {"bend_stiffness", "bend_stiffness_2", "twist_stiffness",
                      "stretch_stiffness"}, 1.3);
  std::vector<double> lp;
  for (const auto& p : in.parameters) lp.push_back(std::log(p.value));
  VecX r;
  Eigen::MatrixXd J;
  ASSERT_TRUE(EvaluateForwardMap(in, lp, &r, &J));
  // Each forward solve is converged to ~1e-9 of the force scale, so a central difference with
  // step h carries ~1e-9 / h of solve noise besides its O(h^2) truncation: h = 1e-3 in log
  // space, and a tolerance of 1e-4 of the column plus 1e-6 of the largest column (EA's effect
  // on a nearly inextensible suture is itself near that noise).
  const double jmax = J.cwiseAbs().maxCoeff();
  for (size_t k = 0; k < lp.size(); ++k) {
    const double h = 1e-3;
    std::vector<double> a = lp, b = lp;
    a[k] += h;
    b[k] -= h;
    VecX ra, rb;
    ASSERT_TRUE(EvaluateForwardMap(in, a, &ra, nullptr));
    ASSERT_TRUE(EvaluateForwardMap(in, b, &rb, nullptr));
    const VecX fd = (ra - rb) / (2 * h);
    const double scale = fd.cwiseAbs().maxCoeff();
    EXPECT_LT((J.col(k) - fd).cwiseAbs().maxCoeff(), 1e-4 * scale + 1e-6 * jmax)
        << in.parameters[k].name;
  }
}

TEST(Fit, RecoversIsotropicBendingFromMarkersNoiseFree) {
  std::mt19937 rng(2);
  FitInput in = Protocol(Suture(), 0.0, &rng);
  AddParameters(&in, {"bend_stiffness"}, 2.0);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_NEAR(Estimate(r, "bend_stiffness").value, 1.0e-6, 0.005e-6);
}

TEST(Fit, RecoversAnisotropicBendingFromSeveralClampOrientations) {
  FitInput truth = Suture();
  truth.material.bend_stiffness_2 = 1.7e-6;
  std::mt19937 rng(3);
  FitInput in = Protocol(truth, 0.0, &rng);
  AddParameters(&in, {"bend_stiffness", "bend_stiffness_2"}, 0.5);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_NEAR(Estimate(r, "bend_stiffness").value, 1.0e-6, 0.005e-6);
  EXPECT_NEAR(Estimate(r, "bend_stiffness_2").value, 1.7e-6, 0.005 * 1.7e-6);
}

// The protocol plus a case twisted by a moment about the clamp axis, sagging under a tip load.
FitInput TwistedProtocol(const FitInput& truth, std::mt19937* rng) {
  FitInput in = Protocol(truth, 0.0, rng);
  LoadCase c = Clamped("twisted", Vec3(1, 0, 0), Vec3(0, 0, 1));
  c.tip_moment = Vec3(3e-6, 0, 0);
  c.tip_force = Vec3(0, 0, -3e-5);
  FitCase fc;
  fc.load_case = c;
  fc.measurements.push_back(Markers(in, Solve(in, c), 10, 3e-4, 0.0, rng));
  in.cases.push_back(fc);
  return in;
}

TEST(Fit, RecoversTwistFromATwistCoupledCase) {
  // Twist shows in the centre-line through anisotropy: the moment twists the section, which
  // turns its stiff and soft bending axes under the sag.
  FitInput truth = Suture();
  truth.material.bend_stiffness_2 = 2.0e-6;
  std::mt19937 rng(4);
  FitInput in = TwistedProtocol(truth, &rng);
  AddParameters(&in, {"bend_stiffness", "twist_stiffness"}, 1.8);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_NEAR(Estimate(r, "twist_stiffness").value, 8e-7, 0.005 * 8e-7);
  EXPECT_NEAR(Estimate(r, "bend_stiffness").value, 1e-6, 0.005e-6);
}

TEST(Fit, TwistOfAnIsotropicRodUnderDeadLoadsIsNotIdentifiable) {
  // Kirchhoff: for an isotropic rod the twisting moment m . d3 is set by the loads (constant
  // without distributed moments), and the centre-line's equations contain it, not GJ. So no
  // centre-line data of such a rod under dead loads determine GJ, however it is twisted. (The
  // discrete rod's averaged directors soften its bending where the twist per edge reaches a
  // radian, a discretization error; the bounds, GJ / B of a solid section within a factor 2,
  // keep the fit where the twist per edge stays below 0.05 rad.)
  FitInput truth = Suture();
  std::mt19937 rng(4);
  FitInput in = TwistedProtocol(truth, &rng);
  AddParameters(&in, {"bend_stiffness", "twist_stiffness"}, 1.8);
  for (Parameter& p : in.parameters)
    if (p.name == "twist_stiffness") p.value = 8e-7, p.min = 4e-7, p.max = 1.6e-6;
  FitOptions options;
  options.trusted_sigmas = true;  // noise-free data: the residual variance would be 0
  const FitResult r = Fit(in, options);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_FALSE(Estimate(r, "twist_stiffness").identifiable);
  EXPECT_FALSE(Estimate(r, "twist_stiffness").std.has_value());
  EXPECT_NEAR(Estimate(r, "bend_stiffness").value, 1e-6, 0.005e-6);
}

TEST(Fit, RecoversStretchFromAStretchedCase) {
  FitInput truth = Suture();
  truth.material.stretch_stiffness = 5.0;  // an elastic tissue strand: visible strain
  std::mt19937 rng(5);
  FitInput in = truth;
  LoadCase c = Clamped("hanging", Vec3(0, 0, -1), Vec3(1, 0, 0));
  c.tip_force = Vec3(0, 0, -0.1);  // 2 % strain
  FitCase fc;
  fc.load_case = c;
  fc.measurements.push_back(Markers(in, Solve(in, c), 10, 1e-5, 0.0, &rng));
  in.cases.push_back(fc);
  AddParameters(&in, {"stretch_stiffness"}, 3.0);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_NEAR(Estimate(r, "stretch_stiffness").value, 5.0, 0.005 * 5.0);
}

TEST(Fit, RecoversBendingFromUnorderedPoints) {
  FitInput truth = Suture();
  std::mt19937 rng(6);
  FitInput in = truth;
  for (const LoadCase& c : {Clamped("flat", Vec3(1, 0, 0), Vec3(0, 0, 1)),
                            Clamped("up", Vec3(1, 0, 0.6), Vec3(0, 0, 1))}) {
    const Mat3X x = Solve(in, c);
    std::vector<Vec3> samples;
    std::uniform_real_distribution<double> U(0.05, 1.0);
    const int n = in.rod.segments;
    for (int k = 0; k < 25; ++k) {  // unordered samples along the centre-line
      const double u = U(rng) * n;
      const int e = std::min(static_cast<int>(u), n - 1);
      samples.push_back((1 - (u - e)) * x.col(e) + (u - e) * x.col(e + 1));
    }
    FitCase fc;
    fc.load_case = c;
    fc.measurements.push_back(
        MakeShapeMeasurement("points3d", "points3d", Points3dObservation(n + 1, samples, 3e-4)));
    in.cases.push_back(fc);
  }
  AddParameters(&in, {"bend_stiffness"}, 2.0);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_NEAR(Estimate(r, "bend_stiffness").value, 1.0e-6, 0.005e-6);
}

TEST(Fit, NoisyEstimatesLieWithinThreeStd) {
  FitInput truth = Suture();
  truth.material.bend_stiffness_2 = 1.4e-6;
  std::mt19937 rng(7);
  FitInput in = Protocol(truth, 3e-4, &rng);
  AddParameters(&in, {"bend_stiffness", "bend_stiffness_2"}, 2.0);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  for (const auto& [name, truth_value] :
       std::vector<std::pair<std::string, double>>{{"bend_stiffness", 1.0e-6},
                                                    {"bend_stiffness_2", 1.4e-6}}) {
    const Parameter& e = Estimate(r, name);
    ASSERT_TRUE(e.std.has_value()) << name << ": " << e.reason;
    EXPECT_LT(std::abs(e.value - truth_value), 3.0 * *e.std) << name;
  }
}

TEST(Fit, ReportedStdMatchesTheSpreadOverSeeds) {
  // 20 noisy replicates of one experiment: the spread of the estimates agrees with the std the
  // fit reports within a factor of 1.5 (docs/solvers.md, "Covariance").
  FitInput truth = Suture(30);
  std::vector<double> estimates, stds;
  for (int seed = 0; seed < 20; ++seed) {
    std::mt19937 rng(100 + seed);
    FitInput in = Protocol(truth, 1e-3, &rng, 8, 1e-3);
    AddParameters(&in, {"bend_stiffness"}, 1.5);
    const FitResult r = Fit(in, FitOptions());
    ASSERT_TRUE(r.success) << r.message;
    const Parameter& e = Estimate(r, "bend_stiffness");
    ASSERT_TRUE(e.std.has_value());
    estimates.push_back(std::log(e.value));
    stds.push_back(*e.std / e.value);
  }
  double mean = 0, var = 0, mean_std = 0;
  for (double v : estimates) mean += v / estimates.size();
  for (double v : estimates) var += (v - mean) * (v - mean) / (estimates.size() - 1);
  for (double s : stds) mean_std += s / stds.size();
  const double ratio = std::sqrt(var) / mean_std;
  EXPECT_GT(ratio, 1 / 1.5) << "spread " << std::sqrt(var) << " reported " << mean_std;
  EXPECT_LT(ratio, 1.5) << "spread " << std::sqrt(var) << " reported " << mean_std;
}

TEST(Fit, TorsionFromAPlaneIsNotIdentifiable) {
  std::mt19937 rng(8);
  FitInput in = Protocol(Suture(), 0.0, &rng);
  in.cases.resize(2);  // planar sag only: nothing twists the rod
  AddParameters(&in, {"bend_stiffness", "twist_stiffness"}, 1.5);
  const FitResult r = Fit(in, FitOptions());
  const Parameter& gj = Estimate(r, "twist_stiffness");
  EXPECT_FALSE(gj.identifiable);
  EXPECT_FALSE(gj.std.has_value());
  EXPECT_FALSE(gj.reason.empty());
  const Parameter& b = Estimate(r, "bend_stiffness");
  EXPECT_TRUE(b.identifiable) << b.reason;
  EXPECT_NEAR(b.value, 1e-6, 0.005e-6);
}

TEST(Fit, IsotropicBendCannotBeSplitIntoB1AndB2) {
  // Every case bends the rod about d2 only (gravity along the clamp normal d1): B1 does not
  // act, so it is reported as not identifiable rather than as a confident number.
  std::mt19937 rng(9);
  FitInput truth = Suture();
  truth.material.bend_stiffness_2 = 1e-6;
  FitInput in = Protocol(truth, 0.0, &rng);
  in.cases.resize(2);
  AddParameters(&in, {"bend_stiffness", "bend_stiffness_2"}, 1.5);
  const FitResult r = Fit(in, FitOptions());
  EXPECT_FALSE(Estimate(r, "bend_stiffness").identifiable);
  EXPECT_TRUE(Estimate(r, "bend_stiffness_2").identifiable);
}

TEST(Fit, BadRequestsAreErrors) {
  std::mt19937 rng(10);
  FitInput in = Protocol(Suture(), 0.0, &rng);
  AddParameters(&in, {}, 1.0);
  EXPECT_THROW(Fit(in, FitOptions()), std::invalid_argument);  // nothing to fit
  in.parameters[0].fit = true;
  in.parameters[0].min = 2e-6;
  in.parameters[0].max = 1e-6;
  EXPECT_THROW(Fit(in, FitOptions()), std::invalid_argument);  // min >= max
  in.parameters[0].min = 1e-9;
  in.parameters[0].max = 1e-7;
  EXPECT_THROW(Fit(in, FitOptions()), std::invalid_argument);  // start outside the bounds
}

TEST(Fit, GlobalStartRecoversFromThreeDecadesOff) {
  std::mt19937 rng(11);
  FitInput in = Protocol(Suture(), 0.0, &rng);
  AddParameters(&in, {"bend_stiffness"}, 1e-3);  // start at 1e-9: three decades too soft
  in.parameters[0].min = 1e-10;
  in.parameters[0].max = 1e-3;
  FitOptions global;
  global.global = true;
  global.global_evaluations = 60;
  const FitResult g = Fit(in, global);
  ASSERT_TRUE(g.success) << g.message;
  EXPECT_NEAR(Estimate(g, "bend_stiffness").value, 1e-6, 0.005e-6);
  // Plain Levenberg–Marquardt from the same start, for comparison: it either fails to reach the
  // truth or needs more iterations than the polish after the global search.
  const FitResult plain = Fit(in, FitOptions());
  const bool plain_recovered =
      plain.success && std::abs(Estimate(plain, "bend_stiffness").value - 1e-6) < 0.005e-6;
  EXPECT_TRUE(!plain_recovered || plain.iterations > g.iterations)
      << "plain LM " << plain.iterations << " iterations, global polish " << g.iterations;
}

// The report's convergence plot reads FitResult::cost_per_iteration: Ceres' cost at the start and
// after every iteration, from the initial to the final cost, never rising (Levenberg–Marquardt
// keeps only steps that lower it), with non-decreasing times within the fit's wall time.
TEST(Fit, CostPerIterationIsRecorded) {
  std::mt19937 rng(3);
  FitInput in = Protocol(Suture(), 3e-4, &rng);
  AddParameters(&in, {"bend_stiffness"}, 3.0);
  const FitResult r = Fit(in, FitOptions());
  ASSERT_TRUE(r.success) << r.message;
  ASSERT_GE(r.iterations, 2);
  ASSERT_EQ(r.cost_per_iteration.size(), static_cast<size_t>(r.iterations + 1));
  ASSERT_EQ(r.seconds_per_iteration.size(), r.cost_per_iteration.size());
  EXPECT_DOUBLE_EQ(r.cost_per_iteration.front(), r.initial_cost);
  EXPECT_DOUBLE_EQ(r.cost_per_iteration.back(), r.final_cost);
  EXPECT_LT(r.final_cost, 0.5 * r.initial_cost);  // started 3x off: the fit had work to do
  for (size_t i = 1; i < r.cost_per_iteration.size(); ++i) {
    EXPECT_LE(r.cost_per_iteration[i], r.cost_per_iteration[i - 1]) << "iteration " << i;
    EXPECT_GE(r.seconds_per_iteration[i], r.seconds_per_iteration[i - 1]) << "iteration " << i;
  }
  EXPECT_GE(r.seconds_per_iteration.front(), 0.0);
  EXPECT_LE(r.seconds_per_iteration.back(), r.seconds);
  EXPECT_EQ(r.global_seconds, 0.0);  // no global search asked for
  // No case has a poke: no sections, one empty entry per shape.
  ASSERT_EQ(r.sections.size(), r.shapes.size());
  for (const Eigen::Matrix3Xd& ring : r.sections) EXPECT_EQ(ring.cols(), 0);
}

// The progress callback (the CLI's progress line): one call per evaluation of the global search,
// counted against its budget with the best cost so far, then one per Levenberg–Marquardt
// iteration with that iteration's cost.
TEST(Fit, ProgressReportsTheGlobalSearchThenEachIteration) {
  std::mt19937 rng(5);
  FitInput in = Protocol(Suture(), 3e-4, &rng);
  AddParameters(&in, {"bend_stiffness"}, 10.0);
  in.parameters[0].min = 1e-8;
  in.parameters[0].max = 1e-4;
  FitOptions options;
  options.global = true;
  options.global_evaluations = 25;
  std::vector<FitIterationInfo> calls;
  options.progress = [&calls](const FitIterationInfo& i) { calls.push_back(i); };
  const FitResult r = Fit(in, options);
  ASSERT_TRUE(r.success) << r.message;
  ASSERT_EQ(r.global_evaluations, 25);
  ASSERT_EQ(calls.size(), static_cast<size_t>(r.global_evaluations + r.iterations + 1));
  for (int k = 0; k < r.global_evaluations; ++k) {
    EXPECT_TRUE(calls[k].global);
    EXPECT_EQ(calls[k].iteration, k + 1);
    EXPECT_EQ(calls[k].budget, 25);
    if (k > 0) {
      EXPECT_LE(calls[k].cost, calls[k - 1].cost);  // the best so far
    }
  }
  for (size_t k = r.global_evaluations; k < calls.size(); ++k) {
    EXPECT_FALSE(calls[k].global);
    EXPECT_EQ(calls[k].iteration, static_cast<int>(k) - r.global_evaluations);
    EXPECT_DOUBLE_EQ(calls[k].cost, r.cost_per_iteration[k - r.global_evaluations]);
  }
  EXPECT_GT(r.global_seconds, 0.0);
  EXPECT_LE(r.global_seconds, r.seconds);
}

}  // namespace
}  // namespace rodfit
