// ResidualVarianceBand (fit.h): the 0.1 % and 99.9 % quantiles of chi-square(dof) / dof that
// `rodfit fit` with trusted sigmas checks the residual variance against. The exact quantiles
// below are from the regularized incomplete gamma function (bisection on P(dof/2, x/2)).
#include <gtest/gtest.h>

#include "rodfit/fit/fit.h"

namespace rodfit {
namespace {

TEST(ResidualVarianceBandTest, MatchesTheChiSquareQuantiles) {
  struct Row {
    int dof;
    double low, high;  // exact chi2_{0.001}(dof) / dof and chi2_{0.999}(dof) / dof
  };
  for (const Row& row : {Row{30, 0.386265, 1.990102}, Row{100, 0.619179, 1.494493},
                         Row{1000, 0.867479, 1.143917}}) {
    SCOPED_TRACE(row.dof);
    const VarianceBand band = ResidualVarianceBand(row.dof);
    EXPECT_NEAR(band.low, row.low, 0.01 * row.low);
    EXPECT_NEAR(band.high, row.high, 0.01 * row.high);
  }
  // Few degrees of freedom: the cube-root approximation is coarser, still within 7 %.
  const VarianceBand ten = ResidualVarianceBand(10);
  EXPECT_NEAR(ten.low, 0.147874, 0.07 * 0.147874);
  EXPECT_NEAR(ten.high, 2.958830, 0.01 * 2.958830);
}

TEST(ResidualVarianceBandTest, NarrowsAroundOneAsTheDataGrow) {
  double previous_width = 1e300;
  for (int dof : {1, 3, 10, 100, 1000, 100000}) {
    SCOPED_TRACE(dof);
    const VarianceBand band = ResidualVarianceBand(dof);
    EXPECT_GE(band.low, 0.0);
    EXPECT_LT(band.low, 1.0);
    EXPECT_GT(band.high, 1.0);
    EXPECT_LT(band.high - band.low, previous_width);
    previous_width = band.high - band.low;
  }
  // The z = 25 of swapped cameras is far outside even a small experiment's band.
  EXPECT_LT(ResidualVarianceBand(20).high, 3.0);
}

}  // namespace
}  // namespace rodfit
