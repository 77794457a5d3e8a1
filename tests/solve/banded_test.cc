// Banded symmetric storage and Cholesky (solve/banded.h) against Eigen's dense LLT: the scalar
// band and the 4 x 4 and 3 x 3 block forms give the same solutions and log-determinant, with a diagonal
// shift, several right-hand sides, and the refusal of an indefinite matrix.
#include <cmath>
#include <random>

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include "rodfit/solve/banded.h"

namespace rodfit {
namespace {

// A random symmetric positive definite matrix with b x b blocks (b = 4: the rod's Hessian; 3: its
// position-only Hessian when the twist is eliminated) coupling at most `q` block neighbours
// (bandwidth b (q + 1) - 1); `indefinite` flips the sign of one diagonal entry far enough to
// make it indefinite.
BandedSymmetric RandomBlockBanded(int blocks, int q, unsigned seed, bool indefinite = false,
                                  int b = 4) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  const int n = b * blocks, p = b * (q + 1) - 1;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  for (int I = 0; I < blocks; ++I)
    for (int J = std::max(0, I - q); J <= I; ++J)
      for (int r = 0; r < b; ++r)
        for (int c = 0; c < b; ++c) {
          const int i = b * I + r, j = b * J + c;
          if (i > j) A(i, j) = A(j, i) = U(rng);
        }
  for (int i = 0; i < n; ++i) A(i, i) = 2.0 * p + U(rng);  // diagonally dominant
  if (indefinite) A(n / 2, n / 2) = -3.0 * p;
  BandedSymmetric B(n, p, b);
  for (int j = 0; j < n; ++j)
    for (int i = j; i <= std::min(n - 1, j + p); ++i) B.At(i, j) = A(i, j);
  return B;
}

void ExpectMatchesDense(const BandedSymmetric& A, double shift) {
  const Eigen::MatrixXd dense =
      A.ToDense() + shift * Eigen::MatrixXd::Identity(A.size(), A.size());
  const Eigen::LLT<Eigen::MatrixXd> llt(dense);
  ASSERT_EQ(llt.info(), Eigen::Success);
  std::mt19937 rng(7);
  std::normal_distribution<double> N(0.0, 1.0);
  Eigen::MatrixXd rhs(A.size(), 3);
  for (int i = 0; i < rhs.size(); ++i) rhs.data()[i] = N(rng);
  const Eigen::MatrixXd x_dense = llt.solve(rhs);
  double logdet = 0.0;
  for (int i = 0; i < A.size(); ++i) logdet += 2.0 * std::log(llt.matrixL()(i, i));

  BandedCholesky chol;
  ASSERT_TRUE(chol.Factor(A, shift));
  Eigen::MatrixXd x = rhs;
  chol.SolveInPlace(x);
  EXPECT_LT((x - x_dense).cwiseAbs().maxCoeff(), 1e-12 * x_dense.cwiseAbs().maxCoeff());
  EXPECT_LT((chol.Solve(rhs.col(1)) - x_dense.col(1)).cwiseAbs().maxCoeff(),
            1e-12 * x_dense.cwiseAbs().maxCoeff());
  EXPECT_NEAR(chol.LogDeterminant(), logdet, 1e-11 * std::abs(logdet));
}

TEST(BandedCholesky, BlockFormMatchesDense) {
  for (int q : {1, 2, 3})
    for (int blocks : {1, 2, 3, 7, 25}) {
      SCOPED_TRACE(testing::Message() << "q = " << q << ", blocks = " << blocks);
      ExpectMatchesDense(RandomBlockBanded(blocks, q, 11 * q + blocks), 0.0);
      ExpectMatchesDense(RandomBlockBanded(blocks, q, 11 * q + blocks), 0.7);
    }
}

TEST(BandedCholesky, ThreeByThreeBlockFormMatchesDense) {
  for (int q : {1, 2}) {
    for (int blocks : {1, 2, 3, 7, 25}) {
      SCOPED_TRACE(testing::Message() << "q = " << q << ", blocks = " << blocks);
      ExpectMatchesDense(RandomBlockBanded(blocks, q, 13 * q + blocks, false, 3), 0.0);
      ExpectMatchesDense(RandomBlockBanded(blocks, q, 13 * q + blocks, false, 3), 0.7);
    }
  }
  // Indefinite: refused, and accepted once shifted, as the scalar and 4 x 4 forms are.
  BandedSymmetric A = RandomBlockBanded(9, 2, 5, /*indefinite=*/true, 3);
  BandedCholesky chol;
  EXPECT_FALSE(chol.Factor(A));
  EXPECT_TRUE(chol.Factor(A, 4.0 * A.bandwidth()));
}

TEST(BandedCholesky, ScalarFormMatchesDense) {
  for (int blocks : {2, 7, 25}) {
    BandedSymmetric A = RandomBlockBanded(blocks, 2, 3 + blocks);
    A.Resize(A.size(), A.bandwidth(), 1);  // same entries, no block structure declared
    ASSERT_EQ(A.block_size(), 1);
    ExpectMatchesDense(A, 0.0);
    ExpectMatchesDense(A, 0.7);
  }
}

TEST(BandedCholesky, RefusesAnIndefiniteMatrixAndAcceptsItShifted) {
  for (int block : {1, 4}) {
    BandedSymmetric A = RandomBlockBanded(10, 2, 5, /*indefinite=*/true);
    A.Resize(A.size(), A.bandwidth(), block);
    BandedCholesky chol;
    EXPECT_FALSE(chol.Factor(A)) << "block size " << block;
    EXPECT_FALSE(chol.valid());
    EXPECT_TRUE(chol.Factor(A, 4.0 * A.bandwidth())) << "block size " << block;
    EXPECT_TRUE(chol.valid());
  }
}

// The rod's Hessian mixes stretch (EA / l ~ 1e5 N/m), bending and twist (GJ / l ~ 1e-4 N m)
// rows. Both forms are invariant under a diagonal scaling D A D in exact arithmetic, and the
// block form must stay so in floating point (its explicit 4 x 4 inverses included): the
// scaled solve, scaled back, agrees with the unscaled one.
TEST(BandedCholesky, SolutionsAreInvariantUnderDiagonalScaling) {
  for (int block : {1, 4}) {
    BandedSymmetric A = RandomBlockBanded(25, 2, 17);
    A.Resize(A.size(), A.bandwidth(), block);
    const int n = A.size();
    Eigen::VectorXd d(n);  // 1e-3 .. 1e3, so the diagonal spans twelve decades
    for (int i = 0; i < n; ++i) d[i] = std::pow(10.0, 3.0 * std::sin(1.7 * i));
    BandedSymmetric scaled = A;
    for (int j = 0; j < n; ++j)
      for (int i = j; i <= std::min(n - 1, j + A.bandwidth()); ++i)
        scaled.At(i, j) = d[i] * A.At(i, j) * d[j];
    Eigen::VectorXd b(n);
    for (int i = 0; i < n; ++i) b[i] = std::cos(0.3 * i);
    BandedCholesky plain, with_scaling;
    ASSERT_TRUE(plain.Factor(A)) << "block size " << block;
    ASSERT_TRUE(with_scaling.Factor(scaled)) << "block size " << block;
    const Eigen::VectorXd x = plain.Solve(b);
    const Eigen::VectorXd x_scaled = with_scaling.Solve(d.cwiseProduct(b));
    EXPECT_LT((d.cwiseProduct(x_scaled) - x).cwiseAbs().maxCoeff(), 1e-12 * x.cwiseAbs().maxCoeff())
        << "block size " << block;
    EXPECT_NEAR(with_scaling.LogDeterminant(),
                plain.LogDeterminant() + 2.0 * d.array().log().sum(), 1e-10 * n)
        << "block size " << block;
  }
}

// A rod-like matrix: soft bending-like blocks plus a stretch spring EA t t^T between
// consecutive position blocks along a random direction t, EA 1e8 times the soft stiffness, so
// each 4 x 4 diagonal block is ill-conditioned in a direction no diagonal scaling removes. The
// factorisation must stay backward stable there: the residual of a solve is at round-off
// relative to |A| |x| (an explicitly inverted diagonal block loses a factor of its condition
// number, which showed in the fit's sensitivities).
TEST(BandedCholesky, SolvesAreBackwardStableWithStiffRotatedSprings) {
  for (int block : {1, 4}) {
    BandedSymmetric A = RandomBlockBanded(30, 2, 23);
    std::mt19937 rng(29);
    std::normal_distribution<double> N(0.0, 1.0);
    const double EA = 1e8 * A.Get(0, 0);
    for (int J = 0; J + 1 < 30; ++J) {
      Eigen::Vector3d t(N(rng), N(rng), N(rng));
      t.normalize();
      const Eigen::Matrix3d K = EA * t * t.transpose();
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c <= r; ++c) {
          A.At(4 * J + r, 4 * J + c) += K(r, c);
          A.At(4 * J + 4 + r, 4 * J + 4 + c) += K(r, c);
        }
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) A.At(4 * J + 4 + r, 4 * J + c) -= K(r, c);
    }
    A.Resize(A.size(), A.bandwidth(), block);
    const Eigen::MatrixXd dense = A.ToDense();
    Eigen::VectorXd b(A.size());
    for (int i = 0; i < b.size(); ++i) b[i] = N(rng);
    BandedCholesky chol;
    ASSERT_TRUE(chol.Factor(A)) << "block size " << block;
    const Eigen::VectorXd x = chol.Solve(b);
    const double residual = (dense * x - b).cwiseAbs().maxCoeff();
    const double scale = dense.cwiseAbs().rowwise().sum().maxCoeff() * x.cwiseAbs().maxCoeff();
    EXPECT_LT(residual, 1e-14 * scale) << "block size " << block;
  }
}

}  // namespace
}  // namespace rodfit
