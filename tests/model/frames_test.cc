// The frame helpers' fast paths (model/frames.h) against the library functions they replace:
// SmallAtan against std::atan, SinCos against std::cos and std::sin, SignedAngle against
// std::atan2 of the same components, and
// UnwrapNear's shortcut against the whole-turn rounding.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "rodfit/model/frames.h"

namespace rodfit {
namespace {

using Vec3 = Vec3T<double>;

// |a - b| in units in the last place of b.
double Ulps(double a, double b) {
  const double ulp = std::nextafter(std::abs(b), INFINITY) - std::abs(b);
  return std::abs(a - b) / ulp;
}

// Both of SmallAtan's branches (|z| <= 1/64 by the short series, up to 1/8 by the long one),
// and angles down to 1e-6 rad, as the solvers take them: within one ulp of std::atan.
TEST(Frames, SmallAtanWithinAnUlpOfAtan) {
  std::mt19937_64 rng(7);
  for (const double limit : {1e-6, 1.0 / 64, 1.0 / 8}) {
    std::uniform_real_distribution<double> z(-limit, limit);
    double worst = 0.0;
    for (int k = 0; k < 1000000; ++k) {
      const double x = z(rng);
      worst = std::max(worst, Ulps(SmallAtan(x), std::atan(x)));
    }
    EXPECT_LE(worst, 1.0) << "|z| <= " << limit;
  }
}

// Both paths of SinCos (series to |x| <= 1/8, libm beyond): within an ulp of std::cos and
// std::sin over 10^6 random arguments per range.
TEST(Frames, SinCosWithinAnUlpOfLibm) {
  std::mt19937_64 rng(5);
  for (const double limit : {1e-6, 1.0 / 64, 1.0 / 8, 4.0}) {
    std::uniform_real_distribution<double> x(-limit, limit);
    double worst_cos = 0.0, worst_sin = 0.0;
    for (int k = 0; k < 1000000; ++k) {
      const double a = x(rng);
      double c, s;
      SinCos(a, &c, &s);
      worst_cos = std::max(worst_cos, Ulps(c, std::cos(a)));
      worst_sin = std::max(worst_sin, Ulps(s, std::sin(a)));
    }
    EXPECT_LE(worst_cos, 1.0) << "|x| <= " << limit;
    EXPECT_LE(worst_sin, 1.0) << "|x| <= " << limit;
  }
}

// Random unit pairs about a random axis, at angles from 1e-8 rad to beyond pi/2 (both paths):
// within two ulps of std::atan2 of the same components (the quotient y / x is rounded once
// before SmallAtan's ulp).
TEST(Frames, SignedAngleMatchesAtan2) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> log_angle(-8.0, 0.3);
  for (int k = 0; k < 100000; ++k) {
    const Vec3 n = Vec3(g(rng), g(rng), g(rng)).normalized();
    Vec3 p(g(rng), g(rng), g(rng));
    p = (p - p.dot(n) * n).normalized();
    const double angle = (k % 2 ? 1.0 : -1.0) * std::pow(10.0, log_angle(rng));
    const Vec3 q = std::cos(angle) * p + std::sin(angle) * n.cross(p);
    const double y = p.cross(q).dot(n), x = p.dot(q);
    const double got = SignedAngle<double>(p, q, n);
    EXPECT_LE(Ulps(got, std::atan2(y, x)), 2.0) << angle;
    EXPECT_NEAR(got, angle, 1e-15 + 1e-14 * std::abs(angle));
  }
}

TEST(Frames, UnwrapNearKeepsTheClosestTurn) {
  constexpr double kTwoPi = 6.283185307179586;
  for (double reference : {-20.0, -3.5, -0.1, 0.0, 2.9, 3.2, 12.0}) {
    for (double angle : {-3.1, -1.0, 0.0, 0.5, 3.1}) {
      const double got = UnwrapNear<double>(angle, angle, reference);
      const double turns = std::round((got - angle) / kTwoPi);
      EXPECT_NEAR(got - angle, turns * kTwoPi, 1e-12);
      EXPECT_LE(std::abs(got - reference), M_PI + 1e-12) << angle << " near " << reference;
    }
  }
}

}  // namespace
}  // namespace rodfit
