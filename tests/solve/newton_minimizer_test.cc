// The one Newton minimizer (solve/newton_minimizer.h) on small problems whose answer is known:
// a convex quadratic (one Newton step), a nonconvex function (the shift policy and the line
// search), a problem that injects a NaN into its residual, matrix or merit at a chosen iteration
// (every such fault ends the solve as kNonFinite, whichever solver states the problem), the
// iteration cap and the time budget.
#include <cmath>
#include <limits>
#include <thread>

#include <gtest/gtest.h>

#include "rodfit/solve/linear_solvers.h"
#include "rodfit/solve/newton_minimizer.h"

namespace rodfit {
namespace {

// f(x) = sum_k w_k phi(x_k) with phi(t) = t^4 / 4 - a t^2 / 2 + b t: nonconvex for a > 0 near 0,
// with a Hessian diagonal 3 t^2 - a. Its minimizers solve t^3 - a t + b = 0.
class Quartic : public NewtonProblem {
 public:
  Quartic(int n, double a, double b) : a_(a), b_(b), x_(VecX::Zero(n)), trial_(x_), prev_(x_) {
    ones_ = VecX::Ones(n);
    solver_.Resize(n);
  }
  VecX& x() { return x_; }
  // Faults: from the evaluation with this index (0-based) on, the residual, the matrix or the
  // merit is NaN (a state the problem cannot evaluate: every later evaluation there fails too).
  enum class Fault { kNone, kResidual, kMatrix, kMerit };
  void Inject(Fault f, int evaluation) { fault_ = f, fault_at_ = evaluation; }
  int evaluations() const { return evaluations_; }

  int NumDofs() const override { return static_cast<int>(x_.size()); }
  void Evaluate(bool matrix, VecX* g) override {
    *g = Gradient(x_);
    if (matrix) {
      solver_.matrix().setZero();
      for (int k = 0; k < x_.size(); ++k) solver_.matrix()(k, k) = 3 * x_[k] * x_[k] - a_;
      if (fault_ == Fault::kMatrix && evaluations_ >= fault_at_)
        solver_.matrix()(0, 0) = std::numeric_limits<double>::quiet_NaN();
    }
    if (fault_ == Fault::kResidual && evaluations_ >= fault_at_)
      (*g)[0] = std::numeric_limits<double>::quiet_NaN();  // first: a max that drops NaNs misses it
    merit_nan_ = fault_ == Fault::kMerit && evaluations_ >= fault_at_;
    ++evaluations_;
  }
  double Energy() override { return F(x_); }
  bool Retract(const VecX& step, double alpha) override {
    trial_ = x_ + alpha * step;
    return true;
  }
  double TrialEnergy() override { return F(trial_); }
  void TrialResidual(VecX* g) override { *g = Gradient(trial_); }
  void AcceptTrial() override {
    prev_.swap(x_);
    x_.swap(trial_);
  }
  void RestorePrevious() override { prev_.swap(x_); }
  StepCaps Caps(const VecX&) override { return {1.0, std::numeric_limits<double>::infinity()}; }
  RelativeStep Measure(const VecX& s) override { return {s.lpNorm<Eigen::Infinity>() / 1e-12, 0.0}; }
  const VecX& NormWeights() override { return ones_; }
  double EnergyNoise(double e) override { return 1e-14 * (std::abs(e) + 1.0); }
  NewtonTolerances Tolerances() override { return {1e-12, 0.0}; }
  double ShiftBase() override { return 1e-6; }
  LinearSolver& Solver() override { return solver_; }

 private:
  double F(const VecX& x) const {
    if (merit_nan_) return std::numeric_limits<double>::quiet_NaN();
    double f = 0.0;
    for (int k = 0; k < x.size(); ++k)
      f += std::pow(x[k], 4) / 4 - a_ * x[k] * x[k] / 2 + b_ * x[k];
    return f;
  }
  VecX Gradient(const VecX& x) const {
    VecX g(x.size());
    for (int k = 0; k < x.size(); ++k) g[k] = x[k] * x[k] * x[k] - a_ * x[k] + b_;
    return g;
  }
  double a_, b_;
  VecX x_, trial_, prev_, ones_;
  DenseCholeskySolver solver_;
  Fault fault_ = Fault::kNone;
  int fault_at_ = -1, evaluations_ = 0;
  bool merit_nan_ = false;
};

TEST(NewtonMinimizer, ConvexQuadraticConvergesInOneStep) {
  Quartic p(5, -1.0, 0.5);  // a < 0: convex everywhere
  p.x().setConstant(1e-9);
  NewtonMinimizer m;
  // From near 0, t^3 + t + 0.5 = 0 is almost linear: a few steps.
  const NewtonSummary r = m.Minimize(&p);
  ASSERT_TRUE(r.converged()) << r.message();
  for (int k = 0; k < 5; ++k)
    EXPECT_NEAR(std::pow(p.x()[k], 3) + p.x()[k] + 0.5, 0.0, 1e-12);
  EXPECT_EQ(r.shifted_factors, 0);
}

TEST(NewtonMinimizer, ShiftsAnIndefiniteMatrixAndReachesAMinimum) {
  // a = 1, b = 0.1: at 0 the Hessian is -1 (indefinite); the minimizers are near +-1.
  Quartic p(3, 1.0, 0.1);
  NewtonMinimizer m;
  const NewtonSummary r = m.Minimize(&p);
  ASSERT_TRUE(r.converged()) << r.message();
  EXPECT_GT(r.shifted_factors, 0);
  for (int k = 0; k < 3; ++k) {
    const double t = p.x()[k];
    EXPECT_NEAR(t * t * t - t + 0.1, 0.0, 1e-12);
    EXPECT_GT(3 * t * t - 1.0, 0.0) << "a minimum, not the maximum near 0";
  }
}

class NanFault : public testing::TestWithParam<std::tuple<Quartic::Fault, int>> {};

// A NaN in the residual, the matrix or the merit, from the first or a later evaluation on, ends
// every solve as kNonFinite: never as converged, never past its cap. (A whole step whose residual
// is NaN is undone first, as any step that did not lower the residual: the NaN then shows at the
// iterate before it.)
TEST_P(NanFault, EndsAsNonFinite) {
  const auto [fault, at] = GetParam();
  Quartic p(4, 1.0, 0.3);
  p.x().setConstant(2.0);
  p.Inject(fault, at);
  for (ChordPolicy chords :
       {ChordPolicy::kOff, ChordPolicy::kWhileContracting, ChordPolicy::kWhenFinishing}) {
    for (bool verify : {false, true}) {
      // Whole steps verified by the residual never read the merit: a NaN there goes unseen, and
      // the residual decides (the problems that verify so are those whose merit only orders
      // trial steps).
      if (verify && fault == Quartic::Fault::kMerit) continue;
      SCOPED_TRACE(testing::Message() << "chords " << static_cast<int>(chords) << " verify "
                                      << verify);
      Quartic q = p;
      NewtonOptions o;
      o.chords = chords;
      o.verify_steps_by_residual = verify;
      NewtonMinimizer m(o);
      const NewtonSummary r = m.Minimize(&q);
      if (q.evaluations() <= at) {
        // Converged before the fault's evaluation: nothing to detect.
        EXPECT_TRUE(r.converged());
        continue;
      }
      EXPECT_EQ(r.termination, Termination::kNonFinite) << r.message();
      EXPECT_STREQ(r.message(), TerminationMessage(Termination::kNonFinite));
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Faults, NanFault,
    testing::Combine(testing::Values(Quartic::Fault::kResidual, Quartic::Fault::kMatrix,
                                     Quartic::Fault::kMerit),
                     testing::Values(0, 1, 2)));

TEST(NewtonMinimizer, StopsAtItsIterationCap) {
  Quartic p(2, 1.0, 0.3);
  p.x().setConstant(50.0);  // far: Newton needs many steps on t^3
  NewtonOptions o;
  o.max_iterations = 2;
  NewtonMinimizer m(o);
  const NewtonSummary r = m.Minimize(&p);
  EXPECT_EQ(r.termination, Termination::kIterationCap);
  EXPECT_LE(r.iterations, 2);
}

// A wall-time budget beyond what the steady clock's 64-bit nanoseconds hold (1e308 s, infinity)
// is no limit: the solve is the one without a budget. Converting it unchecked was undefined
// behaviour (a signed overflow, which the sanitized C API corpus aborted on) and in the release
// build put the deadline in the past: a quasi-static tick stopped at its time budget after one
// Newton iteration (Runtime.HugeTimeBudgetIsNoLimit tests the runtime).
TEST(NewtonMinimizer, HugeTimeBudgetIsNoLimit) {
  Quartic start(2, 1.0, 0.3);
  start.x().setConstant(50.0);  // far: several iterations, so a deadline already past would bite
  Quartic unlimited = start;
  const NewtonSummary expected = NewtonMinimizer().Minimize(&unlimited);
  ASSERT_TRUE(expected.converged()) << expected.message();
  ASSERT_GT(expected.iterations, 1);
  for (const double budget : {1e308, std::numeric_limits<double>::infinity(), 2e9}) {
    Quartic p = start;
    NewtonOptions o;
    o.time_budget = budget;
    const NewtonSummary r = NewtonMinimizer(o).Minimize(&p);
    EXPECT_EQ(r.termination, expected.termination) << "budget " << budget << ": " << r.message();
    EXPECT_EQ(r.iterations, expected.iterations) << "budget " << budget;
    EXPECT_EQ(p.x(), unlimited.x()) << "budget " << budget;
  }
}

// Every termination has its own fixed message.
TEST(NewtonMinimizer, EveryTerminationHasAMessage) {
  for (int t = 0; t <= static_cast<int>(Termination::kRetractionFailed); ++t) {
    const char* m = TerminationMessage(static_cast<Termination>(t));
    ASSERT_NE(m, nullptr);
    EXPECT_STRNE(m, "unknown termination");
    for (int u = 0; u < t; ++u) EXPECT_STRNE(m, TerminationMessage(static_cast<Termination>(u)));
  }
}

// The dense solver finds a NaN or an infinity anywhere in the triangle it factors (it checks the
// factor's diagonal, where any such entry ends up), with and without a shift.
TEST(DenseCholeskySolver, NonFiniteEntriesFailTheFactor) {
  const int n = 40;  // past Eigen's unblocked size: the blocked path too
  for (double bad : {std::numeric_limits<double>::quiet_NaN(),
                     std::numeric_limits<double>::infinity(),
                     -std::numeric_limits<double>::infinity()}) {
    for (int i = 0; i < n; i += 7) {
      for (int j = 0; j <= i; j += 5) {
        for (double shift : {0.0, 1e-3}) {
          DenseCholeskySolver solver;
          solver.Resize(n);
          Eigen::MatrixXd& a = solver.matrix();
          a.setConstant(0.1);
          a.diagonal().setConstant(n);
          ASSERT_TRUE(solver.Factor(shift));
          a(i, j) = a(j, i) = bad;
          EXPECT_FALSE(solver.Factor(shift)) << "entry (" << i << ", " << j << ") = " << bad;
        }
      }
    }
  }
}

// Storage sized ahead has a defined status: ReserveDenseCholesky factors the identity. Eigen's
// sizing constructor LLT(n) left the status uninitialized, and assigning it copied that — undefined
// behaviour (an invalid enum value), which the sanitized runtime tests aborted on in the ring
// solver. The storage is the size asked for, and a copy keeps the status.
TEST(DenseCholeskySolver, ReservedStorageHasADefinedStatus) {
  Eigen::LLT<Eigen::MatrixXd> llt;
  ReserveDenseCholesky(12, &llt);
  EXPECT_EQ(llt.info(), Eigen::Success);
  EXPECT_EQ(llt.matrixLLT().rows(), 12);
  EXPECT_EQ(llt.matrixLLT().cols(), 12);
  const Eigen::LLT<Eigen::MatrixXd> copy = llt;
  EXPECT_EQ(copy.info(), Eigen::Success);
  DenseCholeskySolver solver;
  solver.Resize(12);
  EXPECT_EQ(solver.llt().info(), Eigen::Success);
  EXPECT_EQ(solver.llt().matrixLLT().rows(), 12);
}

}  // namespace
}  // namespace rodfit
