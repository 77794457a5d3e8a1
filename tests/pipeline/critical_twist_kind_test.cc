// The `critical_twist` observation kind (src/rodfit/pipeline/kinds/critical_twist.cc), added as one
// file and its registration line: the roll of the clamp at s = 0 at which a clamped loop loses
// stability, from the experiment (`value_deg`) or a file of trials. On the heavy loop of
// tests/solve/critical_twist_test.cc (1.5 m of wire between coaxial clamps 0.12 m apart, the
// tangent turning by -360 degrees, B = 1e-3 N m^2, GJ = B / 1.3, 5 g/m): its residual's exact
// Jacobian by the fitted log-parameters against central differences of the whole forward map,
// the mirror symmetry of the two roll directions, the range's end as a residual and a warning
// when the model stays stable, the entry's errors, and the reason it exists: with the loop's
// photographed shape alone GJ is not identifiable, with the critical twist B and GJ both are.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "io/temp_dir.h"
#include "pipeline/heavy_loop.h"
#include "rodfit/fit/fit.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/pipeline/synthesize.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

using test::kB;
using test::kEndClamp;
using test::kGJ;
using test::kPi;
using test::LoadLoop;
using test::Loop;
using test::StartLogs;
using test::WriteStart;

// The critical twist's residual (one trial) and its Jacobian row by the fitted log-parameters
// (B, GJ, EA) against central differences of the whole forward map (solve, continuation,
// location), relative step 1e-4 in the log: the located roll is reproducible to ~1e-9 rad
// (docs/solvers.md, "Critical twist"), so the differences carry ~1e-5 rad of round-off per unit
// log; the derivatives are ~13 rad per unit log (B, GJ) and ~1e-5 (EA). The scale invariance
// (stiffnesses and weight scaled together leave the roll unchanged) makes the B and GJ columns
// nearly opposite, checked too. Measured: agreement to 3e-9 relative (B, GJ), 1e-9 absolute (EA).
TEST(CriticalTwistKind, JacobianEqualsCentralDifferencesOfTheForwardMap) {
  TempDir dir;
  const FitInput in = LoadLoop(
      dir, Loop(40, "      - {type: critical_twist, value_deg: 800, sigma_deg: 2}\n", true));
  ASSERT_EQ(in.cases.size(), 1u);
  ASSERT_EQ(in.cases[0].measurements.size(), 1u);
  EXPECT_EQ(in.cases[0].measurements[0]->type(), "critical_twist");
  EXPECT_EQ(in.cases[0].measurements[0]->label(), "critical_twist");
  const std::vector<double> logp = StartLogs(in);
  ASSERT_EQ(logp.size(), 3u);
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  ASSERT_TRUE(EvaluateForwardMap(in, logp, &r, &J));
  ASSERT_EQ(r.size(), 1);
  // 40 segments: the fold lies ~+10 degrees above the converged 815.42 (docs/solvers.md).
  const double sigma = 2.0 * kPi / 180.0;
  const double model_deg = (800.0 * kPi / 180.0 + r[0] * sigma) * 180.0 / kPi;
  EXPECT_NEAR(model_deg, 825.5, 3.0);
  const double h = 1e-4;
  for (int c = 0; c < 3; ++c) {
    std::vector<double> plus = logp, minus = logp;
    plus[c] += h;
    minus[c] -= h;
    Eigen::VectorXd rp, rm;
    ASSERT_TRUE(EvaluateForwardMap(in, plus, &rp, nullptr));
    ASSERT_TRUE(EvaluateForwardMap(in, minus, &rm, nullptr));
    const double fd = (rp[0] - rm[0]) / (2 * h);
    std::printf("column %d: analytic %.9g, central %.9g (per unit log, in sigmas)\n", c, J(0, c),
                fd);
    EXPECT_NEAR(J(0, c), fd, 1e-6 * std::max(1.0, std::abs(fd)) + 1e-5) << "column " << c;
  }
  EXPECT_GT(J(0, 0) * sigma, 10.0);   // dRoll/dlog B ~ +13.7 rad
  EXPECT_LT(J(0, 1) * sigma, -10.0);  // dRoll/dlog GJ ~ -13.0 rad
  EXPECT_LT(std::abs(J(0, 2) * sigma), 1e-3);
}

// The loop is its own mirror image in its plane, so rolling the clamp the other way (negative
// value_deg, range) buckles at the opposite roll: the residuals of +v and -v are opposite, and
// so are their Jacobians.
TEST(CriticalTwistKind, RollingTheOtherWayIsTheMirrorImage) {
  TempDir dir;
  Eigen::VectorXd r[2];
  Eigen::MatrixXd J[2];
  const char* entries[2] = {"      - {type: critical_twist, value_deg: 800, sigma_deg: 2}\n",
                            "      - {type: critical_twist, value_deg: -800, sigma_deg: 2}\n"};
  for (int k = 0; k < 2; ++k) {
    const FitInput in = LoadLoop(dir, Loop(30, entries[k]));
    ASSERT_TRUE(EvaluateForwardMap(in, StartLogs(in), &r[k], &J[k]));
  }
  EXPECT_GT(std::abs(r[0][0]), 1.0);
  EXPECT_NEAR(r[1][0], -r[0][0], 1e-6 * std::abs(r[0][0]));
  EXPECT_LT((J[1] + J[0]).norm(), 1e-5 * J[0].norm());
}

// No loss of stability within max_roll_deg: the residual is taken at the range's end (with no
// derivative), the fit goes on, and the entry's summary warns.
TEST(CriticalTwistKind, StableOverTheRangeIsTheRangesEndAndAWarning) {
  TempDir dir;
  const FitInput in = LoadLoop(
      dir, Loop(30, "      - {type: critical_twist, value_deg: 300, sigma_deg: 5, "
                    "max_roll_deg: 400}\n"));
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  ASSERT_TRUE(EvaluateForwardMap(in, StartLogs(in), &r, &J));
  EXPECT_NEAR(r[0], (400.0 - 300.0) / 5.0, 1e-9);
  EXPECT_EQ(J.norm(), 0.0);
  const Measurement& twist = *in.cases[0].measurements[0];
  ObservationFit of;
  std::vector<MeasurementResidual> per;
  twist.Summarise(Mat3X(), r.data(), &of, &per);
  EXPECT_NEAR(of.rms, 100.0, 1e-6);
  EXPECT_THAT(of.warning, HasSubstr("stays stable up to max_roll_deg 400"));
  ASSERT_EQ(per.size(), 1u);
  EXPECT_EQ(per[0].unit, "deg");
  EXPECT_EQ(per[0].components, 1);
  // A located crossing warns of nothing.
  const FitInput located =
      LoadLoop(dir, Loop(30, "      - {type: critical_twist, value_deg: 800, sigma_deg: 5}\n"));
  ASSERT_TRUE(EvaluateForwardMap(located, StartLogs(located), &r, nullptr));
  ObservationFit quiet;
  per.clear();
  located.cases[0].measurements[0]->Summarise(Mat3X(), r.data(), &quiet, &per);
  EXPECT_TRUE(quiet.warning.empty()) << quiet.warning;
}

std::string LoadError(const TempDir& dir, const std::string& text) {
  try {
    LoadLoop(dir, text);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(CriticalTwistKind, EntryErrorsNameTheirKey) {
  TempDir dir;
  const std::string entry = "      - {type: critical_twist, value_deg: 800, sigma_deg: 2}\n";
  EXPECT_THAT(LoadError(dir, Loop(20, entry, false, "end_pin: {position: [-0.12, 0, 0]}")),
              HasSubstr("needs an end_clamp with a normal"));
  EXPECT_THAT(LoadError(dir, Loop(20, "      - {type: critical_twist, sigma_deg: 2}\n")),
              HasSubstr("needs value_deg"));
  EXPECT_THAT(LoadError(dir, Loop(20, "      - {type: critical_twist, value_deg: 800}\n")),
              HasSubstr("sigma_deg: missing"));
  EXPECT_THAT(
      LoadError(dir, Loop(20, "      - {type: critical_twist, value_deg: 800, sigma_deg: 2, "
                              "max_roll_deg: -1000}\n")),
      HasSubstr("max_roll_deg"));
  EXPECT_THAT(
      LoadError(dir, Loop(20, "      - {type: critical_twist, value_deg: 800, sigma_deg: 2, "
                              "max_roll_deg: 700}\n")),
      HasSubstr("must reach beyond value_deg"));
  dir.Write("t.csv", "roll_deg\n800\n");
  EXPECT_THAT(LoadError(dir, Loop(20, "      - {type: critical_twist, value_deg: 800, "
                                      "file: t.csv, sigma_deg: 2}\n")),
              HasSubstr("value_deg"));
  // A file's trial outside the range, by its line and column.
  dir.Write("far.csv", "roll_deg\n800\n2000\n");
  EXPECT_THAT(LoadError(dir, Loop(20, "      - {type: critical_twist, file: far.csv, "
                                      "sigma_deg: 2}\n")),
              ::testing::AllOf(HasSubstr("far.csv:3"), HasSubstr("roll_deg")));
  // synth has nowhere to write a value that the experiment holds.
  WriteStart(dir);
  const std::string path = dir.Write("value.yaml", Loop(20, entry));
  try {
    Synthesize(LoadExperiment(path), dir.File("out"), SynthOptions());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("give this critical_twist entry a `file:`"));
  }
}

const Parameter& Estimate(const FitResult& r, const std::string& name) {
  for (const Parameter& p : r.parameters)
    if (p.name == name) return p;
  throw std::invalid_argument(name);
}

// Synthetic recovery on the loop at 60 segments: its shape photographed as 30 markers (1 mm
// noise) with or without its critical twist (three trials, 5 degrees each), B and GJ fitted from
// starts 1.6 and 0.6 times the truth. With the shape alone the fit finds B and reports GJ not
// identifiable (the planar loop's shape does not depend on it); with the critical twist both
// are within 3 sigma of the truth.
TEST(CriticalTwistKind, MakesTwistStiffnessIdentifiableOnTheHeavyLoop) {
  for (const bool with_twist : {false, true}) {
    for (const unsigned seed : {1u, 2u}) {
      TempDir dir;
      std::string entries = "      - {type: markers3d, file: markers.csv, sigma: 1.0e-3, count: 30}\n";
      if (with_twist)
        entries += "      - {type: critical_twist, file: twist.csv, sigma_deg: 5, count: 3}\n";
      WriteStart(dir);
      const std::string path = dir.Write("loop.yaml", Loop(60, entries));
      SynthOptions options;
      options.seed = seed;
      Synthesize(LoadExperiment(path), dir.File("out"), options);
      FitInput input = BuildFitInput(LoadExperiment(dir.File("out/experiment.yaml")));
      for (Parameter& p : input.parameters) {
        if (p.name == "bend_stiffness") p.value *= 1.6;
        if (p.name == "twist_stiffness") p.value *= 0.6;
      }
      const auto t0 = std::chrono::steady_clock::now();
      const FitResult r = Fit(input, FitOptions());
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      ASSERT_TRUE(r.success) << r.message;
      const Parameter& b = Estimate(r, "bend_stiffness");
      const Parameter& gj = Estimate(r, "twist_stiffness");
      std::printf("%s, seed %u: B %.6g +- %.3g, GJ %.6g +- %.3g (%s), %d iterations, %.2f s\n",
                  with_twist ? "shape and critical twist" : "shape alone", seed, b.value,
                  b.std ? *b.std : 0.0, gj.value, gj.std ? *gj.std : 0.0,
                  gj.identifiable ? "identifiable" : gj.reason.c_str(), r.iterations, seconds);
      ASSERT_TRUE(b.identifiable && b.std) << b.reason;
      EXPECT_LT(std::abs(b.value - kB), 3.0 * *b.std) << "seed " << seed;
      if (!with_twist) {
        EXPECT_FALSE(gj.identifiable) << "seed " << seed << ": " << gj.value;
        continue;
      }
      ASSERT_TRUE(gj.identifiable && gj.std) << gj.reason;
      EXPECT_LT(std::abs(gj.value - kGJ), 3.0 * *gj.std) << "seed " << seed << ": " << gj.value;
      EXPECT_LT(*gj.std, 0.05 * kGJ);  // a measurement, not a bound
      for (const ObservationFit& o : r.observations) {
        if (o.type != "critical_twist") continue;
        EXPECT_EQ(o.unit, "deg");
        EXPECT_LT(o.rms, 20.0);
        EXPECT_TRUE(o.warning.empty());
      }
    }
  }
}

}  // namespace
}  // namespace rodfit
