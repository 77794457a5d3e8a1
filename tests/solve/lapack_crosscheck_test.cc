// The hand-written banded factorisations (solve/banded.h), behind the minimizer's linear solve
// strategies, checked against LAPACK's (Debian liblapack): dpbtrf/dpbtrs for the symmetric band
// (the rod's Hessian in its 4 x 4 block form, the position-only 3 x 3 block form and the scalar
// band) and dgbtrf/dgbtrs for the general band (the tangent of a case with moments). Both store
// bands the LAPACK way, so the same arrays go to both. Solutions agree to round-off: within a
// small multiple of eps times the condition number (computed densely here).
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "rodfit/solve/banded.h"
#include "rodfit/solve/moment_loads.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics.h"
#include "test_util.h"

extern "C" {
void dpbtrf_(const char* uplo, const int* n, const int* kd, double* ab, const int* ldab, int* info);
void dpbtrs_(const char* uplo, const int* n, const int* kd, const int* nrhs, const double* ab,
             const int* ldab, double* b, const int* ldb, int* info);
void dgbtrf_(const int* m, const int* n, const int* kl, const int* ku, double* ab, const int* ldab,
             int* ipiv, int* info);
void dgbtrs_(const char* trans, const int* n, const int* kl, const int* ku, const int* nrhs,
             const double* ab, const int* ldab, const int* ipiv, double* b, const int* ldb,
             int* info);
}

namespace rodfit {
namespace {

using testing::ModelOf;

double Condition(const Eigen::MatrixXd& A) {
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A);
  const Eigen::VectorXd s = svd.singularValues();
  return s[0] / s[s.size() - 1];
}

// Solves A x = b with LAPACK's banded Cholesky; false when dpbtrf refuses A.
bool LapackCholeskySolve(const BandedSymmetric& A, VecX* x, double* log_det) {
  const int n = A.size(), kd = A.bandwidth(), ld = kd + 1, one = 1;
  Eigen::MatrixXd ab = A.band();  // lower band, column major: LAPACK's layout
  int info = 0;
  dpbtrf_("L", &n, &kd, ab.data(), &ld, &info);
  if (info != 0) return false;
  *log_det = 0.0;
  for (int j = 0; j < n; ++j) *log_det += 2.0 * std::log(ab(0, j));
  dpbtrs_("L", &n, &kd, &one, ab.data(), &ld, x->data(), &n, &info);
  return info == 0;
}

// The same with LAPACK's banded LU.
bool LapackLUSolve(const BandedMatrix& A, const Eigen::MatrixXd& band, VecX* x) {
  const int n = A.size(), kl = A.lower(), ku = A.upper(), ld = 2 * kl + ku + 1, one = 1;
  Eigen::MatrixXd ab = band;
  std::vector<int> ipiv(n);
  int info = 0;
  dgbtrf_(&n, &n, &kl, &ku, ab.data(), &ld, ipiv.data(), &info);
  if (info != 0) return false;
  dgbtrs_("N", &n, &kl, &ku, &one, ab.data(), &ld, ipiv.data(), x->data(), &n, &info);
  return info == 0;
}

void ExpectSameCholesky(const BandedSymmetric& A, const char* what) {
  SCOPED_TRACE(what);
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  VecX b(A.size());
  for (int k = 0; k < b.size(); ++k) b[k] = normal(rng);
  BandedCholesky ours;
  ASSERT_TRUE(ours.Factor(A));
  const VecX x = ours.Solve(b);
  VecX y = b;
  double log_det = 0.0;
  ASSERT_TRUE(LapackCholeskySolve(A, &y, &log_det));
  const double kappa = Condition(A.ToDense());
  const double eps = std::numeric_limits<double>::epsilon();
  EXPECT_LE((x - y).norm(), 100.0 * eps * kappa * y.norm()) << "condition " << kappa;
  // d log det = tr(A^-1 dA): a backward error of eps |A| in either factorisation moves it by at
  // most n eps kappa.
  EXPECT_NEAR(ours.LogDeterminant(), log_det, A.size() * eps * kappa);
}

TEST(LapackCrossCheck, RodHessianBlockCholeskyMatchesDpbtrf) {
  // A suture bent under its tip load (the benchmark scene), its Hessian with the clamp's
  // Dirichlet rows: the statics' and the runtime's matrix, 4 x 4 blocks.
  const Scene s = testing::BenchmarkSuture(40);
  const RodModel model = ModelOf(s);
  RodState state = model.StraightState();
  ASSERT_TRUE(SolveStatics(model, StaticsOptions(), &state).converged);
  VecX g;
  BandedSymmetric H;
  AssembleHessian(model, state, EnergyTerms(), &g, &H);
  ASSERT_EQ(H.block_size(), 4);
  ExpectSameCholesky(H, "4 x 4 blocks");
  // The position-only system (twist eliminated): 3 x 3 blocks.
  if (TwistCanBeEliminated(model)) {
    RodState zero = state;
    SetZeroTwist(model, &zero);
    BandedSymmetric P;
    AssemblePositionHessian(model, zero, EnergyTerms(), &g, &P);
    ExpectSameCholesky(P, "3 x 3 blocks");
  }
}

TEST(LapackCrossCheck, RandomScalarBandCholeskyMatchesDpbtrf) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int p : {1, 3, 7}) {
    const int n = 60;
    BandedSymmetric A(n, p);
    for (int j = 0; j < n; ++j) {
      for (int i = j + 1; i <= std::min(n - 1, j + p); ++i) A.At(i, j) = u(rng);
      A.At(j, j) = 2.0 * p + 1.0 + u(rng);  // diagonally dominant: positive definite
    }
    ExpectSameCholesky(A, ("bandwidth " + std::to_string(p)).c_str());
  }
}

TEST(LapackCrossCheck, BothRefuseAnIndefiniteBand) {
  BandedSymmetric A(20, 2);
  for (int j = 0; j < 20; ++j) A.At(j, j) = (j == 13) ? -1.0 : 3.0;
  for (int j = 0; j + 1 < 20; ++j) A.At(j + 1, j) = 0.5;
  BandedCholesky ours;
  EXPECT_FALSE(ours.Factor(A));
  VecX x = VecX::Ones(20);
  double log_det = 0.0;
  EXPECT_FALSE(LapackCholeskySolve(A, &x, &log_det));
}

void ExpectSameLU(const BandedMatrix& A, const char* what) {
  SCOPED_TRACE(what);
  std::mt19937 rng(11);
  std::normal_distribution<double> normal;
  VecX b(A.size());
  for (int k = 0; k < b.size(); ++k) b[k] = normal(rng);
  BandedLU ours;
  ASSERT_TRUE(ours.Factor(A));
  const VecX x = ours.Solve(b);
  // LAPACK's band with its kl rows of fill-in: rebuilt from the entries, not from our storage.
  const int n = A.size(), kl = A.lower(), ku = A.upper();
  Eigen::MatrixXd band = Eigen::MatrixXd::Zero(2 * kl + ku + 1, n);
  for (int j = 0; j < n; ++j)
    for (int i = std::max(0, j - ku); i <= std::min(n - 1, j + kl); ++i)
      band(kl + ku + i - j, j) = A.At(i, j);
  VecX y = b;
  ASSERT_TRUE(LapackLUSolve(A, band, &y));
  const double kappa = Condition(A.ToDense());
  const double eps = std::numeric_limits<double>::epsilon();
  EXPECT_LE((x - y).norm(), 100.0 * eps * kappa * y.norm()) << "condition " << kappa;
}

TEST(LapackCrossCheck, MomentTangentLUMatchesDgbtrf) {
  // A cantilever with a moment fixed in space at its tip: the balance's tangent is not
  // symmetric (the moment's load stiffness and the twist holonomy).
  Scene s = testing::HeavyCantilever();
  s.cases[0].tip_moment = Vec3(0.02, 0.05, 0.01);
  const RodModel model = ModelOf(s);
  RodState state = model.StraightState();
  ASSERT_TRUE(SolveStatics(model, StaticsOptions(), &state).converged);
  RodFrames frames;
  ComputeRodFrames(model, state, &frames);
  VecX g;
  BandedMatrix J;
  BandedSymmetric H;
  AssembleBalance(model, state, frames, 1.0, &g, &J, &H);
  ASSERT_GT((J.ToDense() - J.ToDense().transpose()).cwiseAbs().maxCoeff(), 0.0);
  ExpectSameLU(J, "moment tangent");
}

TEST(LapackCrossCheck, RandomGeneralBandLUMatchesDgbtrf) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  BandedMatrix A;
  A.Resize(50, 3, 5);
  for (int j = 0; j < 50; ++j)
    for (int i = std::max(0, j - 5); i <= std::min(49, j + 3); ++i) A.At(i, j) = u(rng);
  ExpectSameLU(A, "random band, pivoting needed");
}

}  // namespace
}  // namespace rodfit
