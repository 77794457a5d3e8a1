// Frame operations shared by the energy terms, templated on the scalar so doubles and
// ceres::Jet go through one code path: parallel transport between unit tangents (the minimal
// rotation, Rodrigues form) and the signed angle between two directors about an axis.
#pragma once

#include <cmath>
#include <type_traits>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <ceres/jet_fwd.h>

namespace rodfit {

template <typename T>
using Vec3T = Eigen::Matrix<T, 3, 1>;

/// A double constant as the scalar T, also for nested Jets (whose constructor from double is
/// two conversions away): Cst<T>(0.5) where T(0.5) would do for double and a plain Jet.
template <typename T>
struct ConstantOf {
  static T Make(double v) { return T(v); }
};
template <typename T, int N>
struct ConstantOf<ceres::Jet<T, N>> {
  static ceres::Jet<T, N> Make(double v) { return ceres::Jet<T, N>(ConstantOf<T>::Make(v)); }
};
template <typename T>
T Cst(double v) {
  return ConstantOf<T>::Make(v);
}
template <typename T>
Vec3T<T> CastVec(const Eigen::Vector3d& v) {
  return Vec3T<T>(Cst<T>(v[0]), Cst<T>(v[1]), Cst<T>(v[2]));
}
template <typename T>
const Vec3T<T>& CastVec(const Vec3T<T>& v) {
  return v;
}

/// Parallel transport of u from unit tangent a to unit tangent b: the rotation about a x b taking
/// a to b, smooth at a = b (the common case of a straight or slowly moving rod), singular only
/// for b = -a, which callers prevent by limiting how far a tangent turns in one step. Written as
/// the two reflections it is, first across the plane normal to a + b (a -> -b), then across the
/// plane normal to b (-b -> b), which leave a x b fixed:
///   R u = u - ((a + b).u / (1 + a.b)) (a + b) + 2 (a.u) b,
/// the same rotation as Rodrigues' I + [w]x + [w]x^2 / (1 + a.b), w = a x b, without its three
/// cross products (a third of the instructions of the frame updates, which run several times
/// per dynamic tick). Always inlined: called once per edge in every frame update, where the call
/// itself cost more than the arithmetic (~7 % of a warm re-solve).
template <typename T, typename U>
EIGEN_ALWAYS_INLINE Vec3T<T> ParallelTransport(const Vec3T<T>& a, const Vec3T<T>& b, const Vec3T<U>& u) {
  const Vec3T<T> ut = CastVec<T>(u);
  const Vec3T<T> s = a + b;
  const T k = s.dot(ut) / (Cst<T>(1.0) + a.dot(b));
  return ut - k * s + (Cst<T>(2.0) * a.dot(ut)) * b;
}

/// atan(z) for |z| <= 1/8 by its series to z^17 (the first term left out is below 2^-57 of
/// the sum), about a fifth of the cost of std::atan2 and within an ulp of it (10^7 random
/// arguments). Most angles the solvers take are below 1/64 rad, where the series to z^9 is as
/// exact (the next term is below 2^-60 of the sum), evaluated in Estrin's order: the nested
/// (Horner) form is a chain of dependent multiply-adds whose latency, not its instruction
/// count, made the angle 15 % of a dynamic runtime tick's time.
EIGEN_ALWAYS_INLINE double SmallAtan(double z) {
  const double w = z * z;
  if (w <= 1.0 / 4096) {
    const double w2 = w * w;
    return z * ((1.0 - w * (1.0 / 3)) + w2 * ((1.0 / 5 - w * (1.0 / 7)) + w2 * (1.0 / 9)));
  }
  return z * (1.0 + w * (-1.0 / 3 + w * (1.0 / 5 + w * (-1.0 / 7 + w * (1.0 / 9 + w * (-1.0 / 11 +
              w * (1.0 / 13 + w * (-1.0 / 15 + w * (1.0 / 17)))))))));
}

/// cos(x) and sin(x), for |x| <= 1/8 by their series to x^12 and x^13 (the first terms left
/// out are below 2^-70 of the sums), else std::cos and std::sin: within an ulp of them (10^6
/// random arguments per range, tests/model/frames_test.cc) without libm's call and range
/// reduction. The twist angles of the material frames, which every frame computation turns by,
/// are mostly that small; libm's sine and cosine took 2 % of a dynamic runtime tick.
EIGEN_ALWAYS_INLINE void SinCos(double x, double* cosine, double* sine) {
  const double w = x * x;
  if (w <= 1.0 / 64) {
    const double w2 = w * w;
    // Estrin's order (as SmallAtan): independent products instead of one chain of dependent
    // multiply-adds; the leading term is added last, to a correction below 1/128 of it, so
    // the sum is rounded about once (as one sum the sine was 2 ulps off).
    *cosine = 1.0 + w * ((-1.0 / 2 + w * (1.0 / 24)) +
                         w2 * ((-1.0 / 720 + w * (1.0 / 40320)) +
                               w2 * (-1.0 / 3628800 + w * (1.0 / 479001600))));
    *sine = x + x * w * ((-1.0 / 6 + w * (1.0 / 120)) +
                         w2 * ((-1.0 / 5040 + w * (1.0 / 362880)) +
                               w2 * (-1.0 / 39916800 + w * (1.0 / 6227020800))));
    return;
  }
  *cosine = std::cos(x);
  *sine = std::sin(x);
}

/// Signed angle from p to q about the unit axis n (p, q perpendicular to n). The angles the
/// solvers take (a director against its transport, a reference twist between neighbours) are
/// nearly all small; for doubles those below atan(1/8) = 0.124 rad skip std::atan2, which
/// was 6 % of a dynamic runtime tick (two calls per edge for each of its four frame updates).
template <typename T>
EIGEN_ALWAYS_INLINE T SignedAngle(const Vec3T<T>& p, const Vec3T<T>& q, const Vec3T<T>& n) {
  using std::atan2;
  const T y = p.cross(q).dot(n), x = p.dot(q);
  if constexpr (std::is_same_v<T, double>) {
    if (x > 0.0 && std::abs(y) <= 0.125 * x) return SmallAtan(y / x);
  }
  return atan2(y, x);
}

/// Shifts angle by a whole number of turns so that it is the closest to `reference` (keeps the
/// reference twist continuous in time instead of wrapping at +-pi).
template <typename T>
T UnwrapNear(const T& angle, double angle_value, double reference) {
  constexpr double kTwoPi = 6.283185307179586;
  if (std::abs(reference - angle_value) < 3.0) return angle;  // no whole turn apart (3 < pi)
  const double turns = std::round((reference - angle_value) / kTwoPi);
  return angle + Cst<T>(turns * kTwoPi);
}

}  // namespace rodfit
