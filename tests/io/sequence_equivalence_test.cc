// The sequence fit as restructured (fit/motion_fit.h: each case run once at every vertex, each
// frame a static observation model chained with the vertices' sensitivities) against the
// markers-only evaluation it replaced, on the bundled example data/suture_swing_fit. The former
// evaluation is redone here from the recording read as plain CSV: the case run at the markers'
// own arc lengths and at every time of the file (SampleCaseDynamics with the fit's parameter
// directions), the residual (predicted - recorded) / sigma per coordinate of every recorded
// sample in the file's order, its Jacobian d x(s, t) / d log p / sigma. Both give the same
// residuals and Jacobian to 1e-10 relative, at the start values and at the fit; the fit's
// minimum is that objective's, and its residual and noise counts are the markers'.
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/fit/motion_fit.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/sequence_input.h"
#include "rodfit/solve/case_dynamics.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit {
namespace {

const std::string kExample = std::string(RODFIT_SOURCE_DIR) + "/data/suture_swing_fit/";

struct Former {
  Eigen::VectorXd residuals;  // per recorded sample (file order), per coordinate
  Eigen::MatrixXd jacobian;   // d residuals / d log p
};

// The markers-only evaluation: frame,s,x,y,z at the entry's frame_rate, rows whose coordinates
// are empty or nan not recorded.
Former FormerEvaluation(const Experiment& ex, const Scene& scene,
                        const std::vector<std::string>& names) {
  const ObservationSpec& spec = ex.cases.at(0).observations.at(0);
  const CsvTable table = CsvTable::Read(spec.file);
  const std::vector<double> frame = table.Column("frame"), s = table.Column("s");
  const std::vector<std::string> x = table.TextColumn("x"), y = table.TextColumn("y"),
                                 z = table.TextColumn("z");
  std::map<double, int> times, markers;
  for (int r = 0; r < table.num_rows(); ++r) {
    times.emplace(frame[r] / spec.frame_rate, 0);
    markers.emplace(s[r], 0);
  }
  std::vector<double> t_list, s_list;
  for (auto& [t, index] : times) index = static_cast<int>(t_list.size()), t_list.push_back(t);
  for (auto& [sm, index] : markers) index = static_cast<int>(s_list.size()), s_list.push_back(sm);
  std::vector<ParameterDirection> directions;
  for (const std::string& name : names) {
    Scene up = scene;
    SetMotionParameter(name, std::exp(1.0) * MotionParameter(name, scene), &up);
    directions.push_back(ParameterDirection::Between(scene.material, scene.rod.linear_density,
                                                     up.material, up.rod.linear_density, 1.0));
  }
  const CaseSamples run = SampleCaseDynamics(scene, 0, ex.statics, s_list, t_list, directions);
  EXPECT_TRUE(run.ok) << run.reason;
  std::vector<double> r_rows;
  std::vector<Eigen::RowVectorXd> j_rows;
  for (int r = 0; r < table.num_rows(); ++r) {
    if (x[r].empty() || x[r] == "nan") continue;  // not seen (synth writes empty fields)
    const Eigen::Vector3d p(std::stod(x[r]), std::stod(y[r]), std::stod(z[r]));
    const int k = times.at(frame[r] / spec.frame_rate), m = markers.at(s[r]);
    for (int a = 0; a < 3; ++a) {
      r_rows.push_back((run.x[k](a, m) - p[a]) / spec.sigma);
      j_rows.push_back(run.dx[k].row(3 * m + a) / spec.sigma);
    }
  }
  Former out;
  out.residuals = Eigen::Map<Eigen::VectorXd>(r_rows.data(), r_rows.size());
  out.jacobian.resize(j_rows.size(), names.size());
  for (size_t i = 0; i < j_rows.size(); ++i) out.jacobian.row(i) = j_rows[i];
  return out;
}

// The restructured evaluation's rows in the former order (sample by sample in the file's
// order: ObservationSequence::Frame::sample).
Former Reordered(const ObservationSequence& seq, const SequenceEvaluation& at) {
  Former out;
  out.residuals.resize(at.residuals.size());
  out.jacobian.resize(at.jacobian.rows(), at.jacobian.cols());
  int row = 0;
  for (const ObservationSequence::Frame& frame : seq.frames)
    for (size_t j = 0; j < frame.sample.size(); ++j, row += 3) {
      out.residuals.segment<3>(3 * frame.sample[j]) = at.residuals.segment<3>(row);
      out.jacobian.middleRows<3>(3 * frame.sample[j]) = at.jacobian.middleRows<3>(row);
    }
  EXPECT_EQ(row, at.residuals.size());
  return out;
}

void ExpectSame(const Former& former, const Former& now, const std::string& where) {
  ASSERT_EQ(former.residuals.size(), now.residuals.size()) << where;
  const double r_scale = former.residuals.cwiseAbs().maxCoeff();
  const double r_diff = (former.residuals - now.residuals).cwiseAbs().maxCoeff();
  std::printf("%s: residuals differ by %.2e relative\n", where.c_str(), r_diff / r_scale);
  EXPECT_LT(r_diff, 1e-10 * r_scale) << where;
  for (int k = 0; k < former.jacobian.cols(); ++k) {
    const double j_scale = former.jacobian.col(k).cwiseAbs().maxCoeff();
    const double j_diff = (former.jacobian.col(k) - now.jacobian.col(k)).cwiseAbs().maxCoeff();
    std::printf("%s: Jacobian column %d differs by %.2e relative\n", where.c_str(), k,
                j_diff / j_scale);
    EXPECT_LT(j_diff, 1e-10 * j_scale) << where << " column " << k;
  }
}

TEST(SequenceEquivalence, SutureSwingAsTheMarkersOnlyFitHadIt) {
  const Experiment ex = LoadExperiment(kExample + "experiment.yaml");
  const SequenceInput input = BuildSequenceInput(ex);
  ASSERT_EQ(input.sequences.size(), 1u);
  const ObservationSequence& seq = input.sequences[0];
  const std::vector<std::string> names = FittedNames(ex);
  ASSERT_EQ(names, (std::vector<std::string>{"bend_stiffness", "damping"}));

  const SequenceEvaluation start = EvaluateSequenceResiduals(ex.scene, input.sequences, names,
                                                             ex.statics);
  ASSERT_TRUE(start.ok) << start.reason;
  ExpectSame(FormerEvaluation(ex, ex.scene, names), Reordered(seq, start), "start");

  const MotionFitResult fit = FitSequences(ex.scene, input.sequences, names, ex.statics,
                                           SequenceFitOptionsOf(ex, names));
  ASSERT_TRUE(fit.converged) << fit.message;
  // 94 recorded samples of 3 coordinates, each carrying noise.
  EXPECT_EQ(fit.residuals, 3 * 94);
  EXPECT_EQ(fit.noise_residuals, fit.residuals);
  Scene fitted = ex.scene;
  for (size_t k = 0; k < names.size(); ++k) SetMotionParameter(names[k], fit.values[k], &fitted);
  const SequenceEvaluation at_fit = EvaluateSequenceResiduals(fitted, input.sequences, names,
                                                              ex.statics);
  ASSERT_TRUE(at_fit.ok) << at_fit.reason;
  const Former former = FormerEvaluation(ex, fitted, names);
  ExpectSame(former, Reordered(seq, at_fit), "fit");
  EXPECT_NEAR(0.5 * former.residuals.squaredNorm(), fit.final_cost, 1e-10 * fit.final_cost);
  EXPECT_NEAR(former.residuals.squaredNorm() / (fit.residuals - 2), fit.residual_variance,
              1e-10 * fit.residual_variance);
  // The fit's minimum is the former objective's: a Gauss–Newton step of that objective from it
  // is far below a standard deviation (the search stops at relative changes of 1e-8).
  const Eigen::VectorXd step = -(former.jacobian.transpose() * former.jacobian)
                                    .ldlt()
                                    .solve(former.jacobian.transpose() * former.residuals);
  for (int k = 0; k < 2; ++k) {
    const double log_std = std::sqrt(fit.covariance_log(k, k));
    std::printf("%-15s %.10g +- %.3g: a step of the former objective moves it %.2e std\n",
                names[k].c_str(), fit.values[k], fit.std[k], std::abs(step[k]) / log_std);
    EXPECT_LT(std::abs(step[k]), 1e-3 * log_std) << names[k];
  }
}

}  // namespace
}  // namespace rodfit
