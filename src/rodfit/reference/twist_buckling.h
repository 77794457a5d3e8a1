// Independent reference for the twist buckling of a clamped-clamped Kirchhoff rod (header-only;
// Eigen 3 + C++17; built on kirchhoff_shooting.h and on nothing of rodfit's solvers).
//
// PROBLEM. A rod (kirchhoff_shooting.h's model: inextensible or extensible, no shear, uniform
// gravity) is clamped at s = 0 by clamp A and at s = L by clamp B. Clamp A is rolled about its
// own tangent d3 by the angle `roll` [rad]: its frame is R_A(roll) = R_A * Rot_z(roll), i.e. the
// material frame at s = 0 turns right-handedly about d3 (a positive roll is a positive turn
// about the wire's direction of travel at A). Clamp B is fixed. The roll is an unwrapped
// continuation parameter: R_A(roll + 2 pi) = R_A(roll), but the equilibrium reached by following
// roll continuously from 0 is not the one at roll = 0 (the wire carries the turns), so every
// function here follows the branch that starts at the untwisted (roll = 0) equilibrium.
// The critical roll is the first roll along that branch at which the equilibrium loses
// stability: the second variation of the energy on the admissible variations (both clamps held)
// gets a zero eigenvalue, either where another branch crosses (a bifurcation: the roll keeps
// growing through the point) or where the branch turns back in roll (a fold: the roll is at a
// maximum).
//
// GREENHILL'S PROBLEM (closed form). A straight weightless isotropic rod, both ends clamped at
// distance L, no axial force (EA finite, the clamps exactly L apart), one clamp rolled by Theta:
// the rod stays straight and twisted with the moment M = GJ Theta / L about its axis. Linearised
// about it, the transverse deflection w = x + i y (axis z) satisfies B w''' - i M w'' + c = 0
// (c: the complex transverse shear force, a constant), so w = a0 + a1 s + a2 s^2 + D e^{iks},
// k = M / B. The four clamped conditions w(0) = w'(0) = w(L) = w'(L) = 0 have a nonzero
// solution iff e^{i phi} - 1 = (i phi / 2)(1 + e^{i phi}), phi = k L, i.e. (multiplying by
// e^{-i phi/2}) 2 sin(phi/2) = phi cos(phi/2):  tan(phi/2) = phi/2.  The first positive root is
// phi/2 = 4.4934094579090641753... (the first positive root of tan x = x), so
//     M_c L / B = phi_c = 8.9868189158181283506... = 2.8605933062484055... pi,
// the figure quoted as 2.861 pi for clamped ends in Greenhill's problem (A. G. Greenhill, "On
// the strength of shafting when exposed both to torsion and to end thrust", Proc. Inst. Mech.
// Eng., 1883), which the derivation above reproduces; the critical total roll is
//     Theta_c = phi_c B / GJ.
// The kernel is two-dimensional (w and i w: the buckling mode can lie in any plane through the
// axis), which is why the stability test below is an eigenvalue of a symmetric matrix and not a
// determinant: the determinant of the linearised end map touches zero there without a change
// of sign.
//
// NUMERICS.
// Equilibria: multiple shooting over K = `segments` equal segments, RK4 with `steps` steps
// over the length (kirchhoff_shooting.h's Rk4Step). Unknowns: (n(0), m(0)) and, for k >= 1, the
// state (r, R, n, m) at the start of segment k. All perturbations are in world-frame scaled
// coordinates (dr / L, rotation vector dtheta with R -> exp(dtheta) R, dn / Fs, dm / Ms,
// Fs = Bref / L^2, Ms = Bref / L, Bref = max(B1, B2)); residuals are the 12 continuity
// mismatches per interface and the 6 end-clamp mismatches ((r(L) - r_B) / L,
// log(R(L) R_B^T)).
// Transfer matrices: Phi_k = d(state at the end of segment k) / d(state at its start), 12 x 12,
// by central differences (step `fd_step`) of the RK4 segment map. Everything linear is built
// from them: the shooting Jacobian, its derivative in the roll (rolling clamp A by d(roll) is
// the world rotation d(roll) d3_A of the start frame: Phi_0's rotation columns times d3_A), and
// the stability matrix.
// Stability: Morse's broken extremals. With the junction poses g_1..g_{K-1} (the segment
// boundaries) as variables and each segment solved as a clamped-clamped problem between them,
// the reduced energy W(g_1..g_{K-1}) has, at an equilibrium, the Hessian
//     H_jj = Phi_pp^{j-1} P_{j-1} + P_j Phi_qq^j,   H_{j,j-1} = Phi_pq^{j-1} - Phi_pp^{j-1} P_{j-1} Phi_qq^{j-1},
//     H_{j,j+1} = -P_j,   P_k = (Phi_qp^k)^{-1}
// (q = pose block, p = wrench block of Phi; the gradient of W at junction j is the wrench
// imbalance n, m of the segment ending there minus that of the segment starting there, in the
// scaled units above, so H is the Hessian of W / (Bref / L) in the scaled junction pose
// coordinates). H is symmetric at an equilibrium (its computed asymmetry is reported: a check
// of the transfer matrices). Its inertia equals that of the second variation of the whole rod
// when no segment has a conjugate point of its own (segments short against the buckling
// length; the tests check that the critical roll does not depend on K), so lambda_min(H) > 0
// <=> stable, and lambda_min(H) crosses zero exactly where the clamped problem has a Jacobi
// field, with a change of sign even for the double (symmetric) eigenvalue of Greenhill's rod.
// The sign of det(shooting Jacobian) is recorded too: it changes at folds and simple
// bifurcations, not at double ones.
// Continuation: pseudo-arclength in (unknowns, w roll) with the Euclidean norm, w chosen at the
// start so that the first tangent moves w roll and the scaled unknowns equally (steps are given
// in radians of roll along that first tangent); tangent from the null vector of
// [J_x J_roll / w], oriented by the previous one; predictor along it, chord-Newton corrector
// with the matrix [J_x J_roll / w; t^T] of the last accepted point (corrections orthogonal to
// t); step halved on failure, grown by 1.5 after a success. After every accepted point
// lambda_min(H) is evaluated; when it changes sign the crossing is located by Illinois (regula
// falsi) on the arclength from the last stable point, until the bracket is below
// `locate_tolerance_rad` of roll (|d roll| <= |d s| / w). The kind is a fold if the roll
// component of the tangent changes sign across the bracket, else a bifurcation. No crossing up
// to |roll| = |max_roll_rad| is the outcome kNoneInRange (with lambda_min at the last point),
// not an error; an untwisted equilibrium that is not strictly stable (lambda_min <= 1e-10 of
// the spectrum: unstable, or neutral like a weightless loop that can turn about coaxial clamps)
// is reported with ok = false.
//
// ACCURACY (tests/reference/twist_buckling_test.cc).
// Greenhill: the located critical roll matches phi_c B / GJ within 2e-8 relative (measured
// 1e-10 .. 2e-9 for GJ / B = 0.6, 1/1.3, 1 and K = 2, 3, 4; the floor is the central-difference
// noise of the transfer matrices, not RK4: 500 steps suffice).
// Heavy loop (1.5 m, clamps 0.12 m apart, B = 1e-3 N m^2, GJ = B / 1.3, rho = 5e-3 kg/m):
// a fold at 14.2318089549 rad (815.42 deg); RK4 error ~ h^4 (differences fall by 15.5, 15.9,
// 16.0 from 64 to 1024 steps; 1000 steps are within 1e-9 rad); the same roll to 1e-10 with
// K = 4, 8, 16; the independent discrete energy (finite-difference Hessian, N = 20, 40, 80,
// extrapolated in h^2 and h^4) within 4.6e-6 rad.
// Cost: each continuation point or locate iteration is 25 shots over the length (24 for the
// transfer matrices) plus a few corrector shots. The heavy loop at 1000 steps: 31 points and 23
// locate iterations, 0.9 s of CPU (max_step 1 rad; 1.1 s with 0.5); Greenhill at 500 steps:
// 0.15 s.
//
// API (namespace rodfit_reference):
//   double TanEqualsArgumentFirstRoot();              // 4.4934094579090641753...
//   double GreenhillClampedMomentConstant();          // M_c L / B = 8.98681891581812835...
//   double GreenhillClampedCriticalRoll(B, GJ);       // Theta_c [rad]
//   struct CriticalRollOptions { max_roll_rad, initial_step, max_step, min_step,
//       max_continuation_steps, steps, segments, tolerance, locate_tolerance_rad,
//       max_locate_iterations, fd_step, start_continuation_steps; Check(why) };
//   enum class RollInstability { kBifurcation, kFold, kNoneInRange };
//   struct RollPathPoint { roll_rad, arclength, lambda_min, index, tangent_roll,
//       jacobian_det_sign, twist_moment };
//   struct CriticalRollResult { ok, kind, critical_roll_rad, bracket_rad, lambda_min,
//       tangent_roll, twist_moment, untwisted, shape, critical_mode, path, continuation_steps,
//       corrector_evaluations, locate_iterations, max_hessian_asymmetry, message };
//   CriticalRollResult CriticalRoll(props, clamp_a, clamp_b, options = {},
//                                   initial_guess = nullptr /* (n0, m0) of the untwisted solve */);
//   struct ClampedStability { lambda_min, index, eigenvalues, asymmetry, jacobian_det_sign };
//   ClampedStability StabilityOfClampedEquilibrium(props, equilibrium, segments, steps, fd_step);
// Clamps with a normal parallel to the tangent throw std::invalid_argument (as
// FrameFromTangentNormal); every other failure is a result with ok = false and a message.
#pragma once

#include "rodfit/reference/kirchhoff_shooting.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace rodfit_reference {

// ---------------------------------------------------------------------------------------------
// Greenhill's clamped-clamped constant.

// First positive root of tan x = x, as the root of g(x) = sin x - x cos x = cos x (tan x - x)
// in (pi, 3 pi / 2) (g is smooth there, unlike tan x - x). Newton from 4.49.
inline double TanEqualsArgumentFirstRoot() {
  double x = 4.49;
  for (int i = 0; i < 60; ++i) {
    const double g = std::sin(x) - x * std::cos(x);
    const double dg = x * std::sin(x);  // g'(x)
    const double dx = g / dg;
    x -= dx;
    if (std::abs(dx) <= 4e-16 * x) break;
  }
  return x;
}

// M_c L / B for a straight rod under a twisting moment, both ends clamped, no axial force.
inline double GreenhillClampedMomentConstant() { return 2.0 * TanEqualsArgumentFirstRoot(); }

// Critical total roll [rad] of one clamp of that rod: M_c = GJ Theta_c / L.
inline double GreenhillClampedCriticalRoll(double B, double GJ) {
  return GreenhillClampedMomentConstant() * B / GJ;
}

// ---------------------------------------------------------------------------------------------
// Options and results.

struct CriticalRollOptions {
  double max_roll_rad = 8.0 * 3.14159265358979323846;  // search 0 -> max (negative: other way)
  // Pseudo-arclength steps, in radians of roll along the first tangent (see NUMERICS).
  double initial_step = 0.05;
  double max_step = 0.5;
  double min_step = 1e-7;  // a step halved below this: the continuation failed
  int max_continuation_steps = 5000;
  int steps = 2000;       // RK4 steps over the whole length
  int segments = 8;       // shooting segments = Morse segments (>= 2)
  double tolerance = 1e-10;  // scaled residual 2-norm of every continuation point
  double locate_tolerance_rad = 1e-9;  // final bracket, in roll (bounds the roll's error)
  int max_locate_iterations = 80;
  double fd_step = 1e-6;  // central-difference step of the transfer matrices (scaled state)
  int start_continuation_steps = 20;  // homotopy steps of the untwisted solve (SolveKirchhoff)

  bool Check(std::string* why) const {
    auto fail = [&](const char* m) {
      if (why) *why = m;
      return false;
    };
    if (!std::isfinite(max_roll_rad) || max_roll_rad == 0.0) return fail("max_roll_rad must be finite and nonzero");
    if (!(initial_step > 0 && max_step >= initial_step && min_step > 0 && min_step <= initial_step))
      return fail("need 0 < min_step <= initial_step <= max_step");
    if (segments < 2) return fail("segments must be >= 2 (the stability matrix lives on the junctions)");
    if (steps < segments) return fail("steps must be >= segments");
    if (!(tolerance > 0 && locate_tolerance_rad > 0 && fd_step > 0)) return fail("tolerances must be > 0");
    if (max_continuation_steps < 1 || max_locate_iterations < 1 || start_continuation_steps < 1)
      return fail("iteration caps must be >= 1");
    return true;
  }
};

enum class RollInstability { kBifurcation, kFold, kNoneInRange };

inline const char* RollInstabilityName(RollInstability k) {
  switch (k) {
    case RollInstability::kBifurcation: return "bifurcation";
    case RollInstability::kFold: return "fold";
    case RollInstability::kNoneInRange: return "none in range";
  }
  return "?";
}

struct RollPathPoint {
  double roll_rad = 0.0;
  double arclength = 0.0;       // pseudo-arclength from the untwisted point [rad of roll]
  double lambda_min = 0.0;      // smallest eigenvalue of the stability matrix H
  int index = 0;                // number of negative eigenvalues of H
  double tangent_roll = 0.0;    // roll component of the unit tangent (sign change: a fold)
  int jacobian_det_sign = 0;    // sign of det of the shooting Jacobian J_x
  double twist_moment = 0.0;    // m(0) . d3(0) [N m]: the torque clamp A applies is minus this
};

struct CriticalRollResult {
  bool ok = false;  // false: no answer (message says why); true: `kind` is the outcome
  RollInstability kind = RollInstability::kNoneInRange;
  // kBifurcation / kFold: the located roll; kNoneInRange: the last roll reached (>= the range).
  double critical_roll_rad = std::numeric_limits<double>::quiet_NaN();
  double bracket_rad = std::numeric_limits<double>::quiet_NaN();  // final arclength bracket
  double lambda_min = std::numeric_limits<double>::quiet_NaN();   // at critical_roll_rad
  double tangent_roll = std::numeric_limits<double>::quiet_NaN(); // at critical_roll_rad
  double twist_moment = std::numeric_limits<double>::quiet_NaN(); // m(0) . d3(0) there [N m]
  ShootingResult untwisted;  // the roll = 0 equilibrium the branch starts from
  ShootingResult shape;      // the equilibrium at critical_roll_rad
  // Eigenvector of H for lambda_min: (dr / L, dtheta) of junction 1, 2, ..., K-1.
  Eigen::VectorXd critical_mode;
  std::vector<RollPathPoint> path;  // the accepted continuation points
  int continuation_steps = 0;
  int corrector_evaluations = 0;  // residual evaluations (one shot each)
  int locate_iterations = 0;
  double max_hessian_asymmetry = 0.0;  // max over points of |H - H^T|_max / |H|_max
  std::string message;
};

struct ClampedStability {
  double lambda_min = 0.0;
  int index = 0;  // negative eigenvalues of H
  Eigen::VectorXd eigenvalues;  // of (H + H^T) / 2, ascending
  Eigen::VectorXd mode;         // eigenvector of lambda_min
  double asymmetry = 0.0;       // |H - H^T|_max / |H|_max
  int jacobian_det_sign = 0;
};

// ---------------------------------------------------------------------------------------------
// Machinery.

namespace detail {

using Vector12 = Eigen::Matrix<double, 12, 1>;
using Matrix12 = Eigen::Matrix<double, 12, 12>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

struct RollProblem {
  RodProperties p;
  Eigen::Vector3d f = Eigen::Vector3d::Zero();  // distributed force
  Eigen::Vector3d rA = Eigen::Vector3d::Zero(), d3A = Eigen::Vector3d::UnitZ();
  Eigen::Quaterniond qA0 = Eigen::Quaterniond::Identity();  // clamp A frame at roll 0
  Eigen::Vector3d rB = Eigen::Vector3d::Zero();
  Eigen::Quaterniond qB = Eigen::Quaterniond::Identity();
  int K = 2;
  std::vector<double> sb;  // segment boundaries
  std::vector<int> nst;    // RK4 steps per segment
  double L = 1, Fs = 1, Ms = 1, fd = 1e-6;
  // The continuation variable is roll_weight * roll, so that the arclength steps move the roll
  // and the scaled unknowns comparably (set from the first tangent).
  double roll_weight = 1.0;
  int N = 6;

  void Init(const RodProperties& props, int segments, int steps, double fd_step) {
    p = props;
    f = props.DistributedForce();
    K = segments;
    L = props.length;
    const double Bref = std::max(props.B1, props.B2);
    Fs = Bref / (L * L);
    Ms = Bref / L;
    fd = fd_step;
    N = 6 + 12 * (K - 1);
    const int per = std::max(1, (steps + K - 1) / K);  // as SolveKirchhoff splits them
    sb.clear();
    for (int k = 0; k <= K; ++k) sb.push_back(L * k / K);
    sb.back() = L;
    nst.assign(K, per);
  }

  Eigen::Quaterniond ClampA(double roll) const {
    return (qA0 * QuatExp(roll * Eigen::Vector3d::UnitZ())).normalized();
  }

  int Col(int k) const { return k == 0 ? 0 : 6 + 12 * (k - 1); }

  RodState Integrate(const RodState& x, int k) const {
    return Unpack(IntegrateSegment(p, f, Pack(x), sb[k], sb[k + 1], nst[k]));
  }

  RodState Retract(const RodState& x, const Vector12& d) const {
    RodState y = x;
    y.r += L * d.segment<3>(0);
    y.q = (QuatExp(d.segment<3>(3)) * x.q).normalized();
    y.n += Fs * d.segment<3>(6);
    y.m += Ms * d.segment<3>(9);
    return y;
  }

  Vector12 Difference(const RodState& a, const RodState& b) const {
    Vector12 d;
    d.segment<3>(0) = (a.r - b.r) / L;
    d.segment<3>(3) = QuatLog(a.q * b.q.conjugate());
    d.segment<3>(6) = (a.n - b.n) / Fs;
    d.segment<3>(9) = (a.m - b.m) / Ms;
    return d;
  }

  void SetRoll(std::vector<RodState>& starts, double roll) const {
    starts[0].r = rA;
    starts[0].q = ClampA(roll);
  }

  void Apply(std::vector<RodState>& starts, const Eigen::VectorXd& dz) const {
    starts[0].n += Fs * dz.segment<3>(0);
    starts[0].m += Ms * dz.segment<3>(3);
    for (int k = 1; k < K; ++k) starts[k] = Retract(starts[k], dz.segment<12>(Col(k)));
  }

  // Continuity blocks, then the end clamp (starts[0] must carry clamp A's pose).
  Eigen::VectorXd Residual(const std::vector<RodState>& starts) const {
    Eigen::VectorXd F(N);
    RodState e;
    for (int k = 0; k < K; ++k) {
      e = Integrate(starts[k], k);
      if (k + 1 < K) F.segment<12>(12 * k) = Difference(e, starts[k + 1]);
    }
    const int r0 = 12 * (K - 1);
    F.segment<3>(r0) = (e.r - rB) / L;
    F.segment<3>(r0 + 3) = QuatLog(e.q * qB.conjugate());
    return F;
  }
};

struct Linearization {
  std::vector<Matrix12> Phi;
  Eigen::MatrixXd Jx;     // N x N
  Eigen::VectorXd Jroll;  // N
  ClampedStability stab;
};

inline Matrix12 TransferMatrix(const RollProblem& P, const RodState& start, int k) {
  const RodState base = P.Integrate(start, k);
  Matrix12 Phi;
  for (int j = 0; j < 12; ++j) {
    Vector12 d = Vector12::Zero();
    d(j) = P.fd;
    const RodState ep = P.Integrate(P.Retract(start, d), k);
    const RodState em = P.Integrate(P.Retract(start, -d), k);
    Phi.col(j) = (P.Difference(ep, base) - P.Difference(em, base)) / (2.0 * P.fd);
  }
  return Phi;
}

// Reduced-energy Hessian on the junction poses (see the top comment) and its spectrum.
inline ClampedStability JunctionStability(const std::vector<Matrix12>& Phi) {
  const int K = static_cast<int>(Phi.size());
  const int M = 6 * (K - 1);
  std::vector<Matrix6> Pinv(K), Qqq(K), Ppq(K), Ppp(K);
  for (int k = 0; k < K; ++k) {
    Qqq[k] = Phi[k].block<6, 6>(0, 0);
    Ppq[k] = Phi[k].block<6, 6>(6, 0);
    Ppp[k] = Phi[k].block<6, 6>(6, 6);
    Pinv[k] = Phi[k].block<6, 6>(0, 6).fullPivLu().inverse();
  }
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(M, M);
  for (int j = 1; j < K; ++j) {
    const int b = 6 * (j - 1);
    H.block<6, 6>(b, b) = Ppp[j - 1] * Pinv[j - 1] + Pinv[j] * Qqq[j];
    if (j >= 2) H.block<6, 6>(b, b - 6) = Ppq[j - 1] - Ppp[j - 1] * Pinv[j - 1] * Qqq[j - 1];
    if (j + 1 <= K - 1) H.block<6, 6>(b, b + 6) = -Pinv[j];
  }
  ClampedStability s;
  const double scale = H.cwiseAbs().maxCoeff();
  s.asymmetry = scale > 0 ? (H - H.transpose()).cwiseAbs().maxCoeff() / scale : 0.0;
  const Eigen::MatrixXd Hs = 0.5 * (H + H.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Hs);
  s.eigenvalues = es.eigenvalues();
  s.lambda_min = s.eigenvalues(0);
  s.mode = es.eigenvectors().col(0);
  s.index = 0;
  for (int i = 0; i < M; ++i) s.index += s.eigenvalues(i) < 0 ? 1 : 0;
  return s;
}

inline int DeterminantSign(const Eigen::MatrixXd& A) {
  Eigen::PartialPivLU<Eigen::MatrixXd> lu(A);
  int sign = static_cast<int>(lu.permutationP().determinant());  // +-1
  const Eigen::MatrixXd& U = lu.matrixLU();
  for (Eigen::Index i = 0; i < U.rows(); ++i) {
    if (U(i, i) == 0.0) return 0;
    if (U(i, i) < 0) sign = -sign;
  }
  return sign;
}

inline Linearization Linearize(const RollProblem& P, const std::vector<RodState>& starts) {
  Linearization lin;
  const int K = P.K, N = P.N;
  lin.Phi.resize(K);
  for (int k = 0; k < K; ++k) lin.Phi[k] = TransferMatrix(P, starts[k], k);
  lin.Jx = Eigen::MatrixXd::Zero(N, N);
  lin.Jroll = Eigen::VectorXd::Zero(N);
  for (int k = 0; k + 1 < K; ++k) {
    if (k == 0) lin.Jx.block(0, 0, 12, 6) = lin.Phi[0].rightCols<6>();
    else lin.Jx.block(12 * k, P.Col(k), 12, 12) = lin.Phi[k];
    lin.Jx.block(12 * k, P.Col(k + 1), 12, 12) -= Matrix12::Identity();
  }
  const int r0 = 12 * (K - 1);
  if (K == 1) lin.Jx.block(r0, 0, 6, 6) = lin.Phi[0].block<6, 6>(0, 6);
  else lin.Jx.block(r0, P.Col(K - 1), 6, 12) = lin.Phi[K - 1].topRows<6>();
  // Rolling clamp A by d(roll) turns the start frame by the world rotation d(roll) d3_A.
  const int rows = K == 1 ? 6 : 12;
  lin.Jroll.head(rows) = lin.Phi[0].block(0, 3, rows, 3) * P.d3A;
  if (K >= 2) lin.stab = JunctionStability(lin.Phi);
  lin.stab.jacobian_det_sign = DeterminantSign(lin.Jx);
  return lin;
}

// Unit tangent of the solution curve: null vector of [J_x J_roll], oriented by `previous`.
inline Eigen::VectorXd CurveTangent(const RollProblem& P, const Linearization& lin,
                                    const Eigen::VectorXd& previous) {
  const int N = P.N;
  Eigen::MatrixXd A(N + 1, N + 1);
  A.topLeftCorner(N, N) = lin.Jx;
  A.topRightCorner(N, 1) = lin.Jroll / P.roll_weight;
  A.bottomRows(1) = previous.transpose();
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(N + 1);
  rhs(N) = 1.0;
  Eigen::VectorXd t = A.fullPivLu().solve(rhs);
  return t / t.norm();
}

struct CurvePoint {
  std::vector<RodState> starts;
  double roll = 0.0;
  double arclength = 0.0;
  double residual = 0.0;
  Linearization lin;
  Eigen::VectorXd tangent;
};

// Chord-Newton corrector from `a` along its tangent by `ds`: F = 0 and t_a . (z - z_a) = ds.
inline bool Correct(const RollProblem& P, const CurvePoint& a,
                    const Eigen::PartialPivLU<Eigen::MatrixXd>& chord, double ds, double tol,
                    CurvePoint* out, int* evaluations) {
  const int N = P.N;
  CurvePoint c;
  c.starts = a.starts;
  P.Apply(c.starts, ds * a.tangent.head(N));
  c.roll = a.roll + ds * a.tangent(N) / P.roll_weight;
  Eigen::VectorXd w = ds * a.tangent;  // displacement from a in the increments' chart
  double prev = kInfinity;
  for (int it = 0; it < 30; ++it) {
    P.SetRoll(c.starts, c.roll);
    const Eigen::VectorXd F = P.Residual(c.starts);
    ++*evaluations;
    const double norm = F.norm();
    if (!std::isfinite(norm)) return false;
    if (norm < tol) {
      c.residual = norm;
      c.arclength = a.arclength + ds;
      *out = std::move(c);
      return true;
    }
    // The chord iteration contracts linearly; stop when it does not (step too long).
    if (it >= 2 && norm > 0.7 * prev) return false;
    prev = norm;
    Eigen::VectorXd rhs(N + 1);
    rhs.head(N) = -F;
    rhs(N) = ds - a.tangent.dot(w);
    const Eigen::VectorXd d = chord.solve(rhs);
    if (!d.allFinite()) return false;
    P.Apply(c.starts, d.head(N));
    c.roll += d(N) / P.roll_weight;
    w += d;
  }
  return false;
}

inline Eigen::PartialPivLU<Eigen::MatrixXd> ChordMatrix(const RollProblem& P,
                                                        const CurvePoint& a) {
  const int N = P.N;
  Eigen::MatrixXd A(N + 1, N + 1);
  A.topLeftCorner(N, N) = a.lin.Jx;
  A.topRightCorner(N, 1) = a.lin.Jroll / P.roll_weight;
  A.bottomRows(1) = a.tangent.transpose();
  return Eigen::PartialPivLU<Eigen::MatrixXd>(A);
}

inline ShootingResult ShapeOf(const RollProblem& P, const std::vector<RodState>& starts,
                              double residual) {
  ShootingResult res;
  res.props = P.p;
  res.distributed_force = P.f;
  std::vector<double> s;
  std::vector<StateVector> ys;
  StateVector yL = StateVector::Zero();
  for (int k = 0; k < P.K; ++k) {
    yL = IntegrateSegment(P.p, P.f, Pack(starts[k]), P.sb[k], P.sb[k + 1], P.nst[k], &s, &ys,
                          k == P.K - 1);
  }
  FillSamples(res, s, ys);
  res.n0 = starts[0].n;
  res.m0 = starts[0].m;
  res.nL = yL.segment<3>(7);
  res.mL = yL.segment<3>(10);
  res.converged = true;
  res.residual = residual;
  res.lambda = 1.0;
  res.message = "converged";
  return res;
}

inline std::vector<RodState> SegmentStarts(const RollProblem& P, const ShootingResult& eq) {
  std::vector<RodState> starts(P.K);
  for (int k = 0; k < P.K; ++k) starts[k] = eq.StateAt(P.sb[k]);
  return starts;
}

}  // namespace detail

// Stability of a given clamped-clamped equilibrium (e.g. a SolveKirchhoff result with a kClamp
// end): the junction Hessian H on `segments` equal segments, each integrated with
// steps / segments RK4 steps from the equilibrium's own states.
inline ClampedStability StabilityOfClampedEquilibrium(const RodProperties& props,
                                                      const ShootingResult& equilibrium,
                                                      int segments = 8, int steps = 2000,
                                                      double fd_step = 1e-6) {
  if (segments < 2) throw std::invalid_argument("StabilityOfClampedEquilibrium: segments < 2");
  detail::RollProblem P;
  P.Init(props, segments, steps, fd_step);
  const std::vector<RodState> starts = detail::SegmentStarts(P, equilibrium);
  return detail::Linearize(P, starts).stab;
}

namespace detail {

// The roll problem between clamp A (rolled) and clamp B (fixed) on opts' segments and steps.
inline void SetUpRollProblem(const RodProperties& props, const ClampSpec& clamp_a,
                             const ClampSpec& clamp_b, const CriticalRollOptions& opts,
                             RollProblem* P) {
  P->Init(props, opts.segments, opts.steps, opts.fd_step);
  P->rA = clamp_a.position;
  P->qA0 = Eigen::Quaterniond(FrameFromTangentNormal(clamp_a.tangent, clamp_a.normal)).normalized();
  P->d3A = clamp_a.tangent.normalized();
  P->rB = clamp_b.position;
  P->qB = Eigen::Quaterniond(FrameFromTangentNormal(clamp_b.tangent, clamp_b.normal)).normalized();
}

// The path's first point: the untwisted equilibrium at roll 0, its tangent towards `direction`
// (+1 or -1). Sets P->roll_weight.
inline CurvePoint RollStart(RollProblem* P, const ShootingResult& untwisted, double direction) {
  CurvePoint a;
  a.starts = SegmentStarts(*P, untwisted);
  a.roll = 0.0;
  P->SetRoll(a.starts, 0.0);
  a.residual = P->Residual(a.starts).norm();
  a.lin = Linearize(*P, a.starts);
  Eigen::VectorXd seed = Eigen::VectorXd::Zero(P->N + 1);
  seed(P->N) = direction;
  a.tangent = CurveTangent(*P, a.lin, seed);
  // Weight the roll so that the first tangent moves it and the unknowns equally.
  P->roll_weight = std::clamp(a.tangent.head(P->N).norm() / std::abs(a.tangent(P->N)), 1.0, 1e3);
  a.tangent = CurveTangent(*P, a.lin, seed);
  return a;
}

// A point of the path recorded in res (its path and largest Hessian asymmetry).
inline void RecordPathPoint(const RollProblem& P, const CurvePoint& c, CriticalRollResult* res) {
  RollPathPoint pp;
  pp.roll_rad = c.roll;
  pp.arclength = c.arclength / P.roll_weight;
  pp.lambda_min = c.lin.stab.lambda_min;
  pp.index = c.lin.stab.index;
  pp.tangent_roll = c.tangent(P.N) / P.roll_weight;
  pp.jacobian_det_sign = c.lin.stab.jacobian_det_sign;
  pp.twist_moment = c.starts[0].m.dot(P.d3A);
  res->path.push_back(pp);
  res->max_hessian_asymmetry = std::max(res->max_hessian_asymmetry, c.lin.stab.asymmetry);
}

// 2. Pseudo-arclength continuation from *a until lambda_min changes sign or the range is passed.
// Steps and the locate tolerance are given in radians of roll along the initial tangent.
// True: *b is the first point with lambda_min <= 0, *a the last before it and *chord its chord
// matrix. False: res is final (stable through the range, or the continuation stopped: why).
inline bool FollowRoll(const RollProblem& P, const CriticalRollOptions& opts, CurvePoint* a,
                       Eigen::PartialPivLU<Eigen::MatrixXd>* chord, CurvePoint* b,
                       CriticalRollResult* res) {
  const double direction = opts.max_roll_rad > 0 ? 1.0 : -1.0;
  const double range = std::abs(opts.max_roll_rad);
  const double unit = P.roll_weight;
  double ds = opts.initial_step * unit;
  for (;;) {
    if (res->continuation_steps >= opts.max_continuation_steps) {
      res->message = "continuation step cap reached at roll " + std::to_string(a->roll);
      res->shape = ShapeOf(P, a->starts, a->residual);
      return false;
    }
    CurvePoint c;
    if (!Correct(P, *a, *chord, ds, opts.tolerance, &c, &res->corrector_evaluations)) {
      ds *= 0.5;
      if (ds < opts.min_step * unit) {
        res->message = "continuation stalled at roll " + std::to_string(a->roll) +
                       " rad (step below min_step)";
        res->shape = ShapeOf(P, a->starts, a->residual);
        return false;
      }
      continue;
    }
    ++res->continuation_steps;
    c.lin = Linearize(P, c.starts);
    c.tangent = CurveTangent(P, c.lin, a->tangent);
    RecordPathPoint(P, c, res);
    if (c.lin.stab.lambda_min <= 0.0) {
      *b = std::move(c);
      return true;
    }
    if (direction * c.roll > range) {
      res->ok = true;
      res->kind = RollInstability::kNoneInRange;
      res->critical_roll_rad = c.roll;
      res->lambda_min = c.lin.stab.lambda_min;
      res->tangent_roll = c.tangent(P.N) / P.roll_weight;
      res->twist_moment = c.starts[0].m.dot(P.d3A);
      res->shape = ShapeOf(P, c.starts, c.residual);
      res->critical_mode = c.lin.stab.mode;
      res->message = "stable up to roll " + std::to_string(c.roll) + " rad (lambda_min " +
                     std::to_string(c.lin.stab.lambda_min) + ")";
      return false;
    }
    *a = std::move(c);
    *chord = ChordMatrix(P, *a);
    ds = std::min(opts.max_step * unit, ds * 1.5);
  }
}

// 3. Locate the crossing on the arclength from a (lambda > 0) to b (lambda <= 0): Illinois.
// Fills res with the point found (or why it was not located to tolerance).
inline void LocateCrossing(const RollProblem& P, const CriticalRollOptions& opts,
                           const CurvePoint& a, const Eigen::PartialPivLU<Eigen::MatrixXd>& chord,
                           const CurvePoint& b, CriticalRollResult* res) {
  const double direction = opts.max_roll_rad > 0 ? 1.0 : -1.0;
  const double range = std::abs(opts.max_roll_rad);
  const double unit = P.roll_weight;
  const bool fold = a.tangent(P.N) * b.tangent(P.N) < 0.0;
  double s_lo = 0.0, f_lo = a.lin.stab.lambda_min;
  double s_hi = b.arclength - a.arclength, f_hi = b.lin.stab.lambda_min;
  CurvePoint best = b;
  int side = 0;
  const double s_tol = opts.locate_tolerance_rad * unit;  // |d roll| <= |d s| / unit
  while (s_hi - s_lo > s_tol && f_hi != 0.0 &&
         res->locate_iterations < opts.max_locate_iterations) {
    ++res->locate_iterations;
    double s = (s_lo * f_hi - s_hi * f_lo) / (f_hi - f_lo);
    const double w = s_hi - s_lo;
    if (!(s > s_lo + 1e-3 * w && s < s_hi - 1e-3 * w)) s = 0.5 * (s_lo + s_hi);
    CurvePoint c;
    if (!Correct(P, a, chord, s, opts.tolerance, &c, &res->corrector_evaluations)) {
      res->message = "corrector failed while locating the crossing near roll " +
                     std::to_string(a.roll);
      res->shape = ShapeOf(P, a.starts, a.residual);
      return;
    }
    c.lin = Linearize(P, c.starts);
    c.tangent = CurveTangent(P, c.lin, a.tangent);
    const double fc = c.lin.stab.lambda_min;
    if (fc > 0.0) {
      s_lo = s;
      f_lo = fc;
      if (side == -1) f_hi *= 0.5;  // Illinois: the retained end's value halved
      side = -1;
    } else {
      s_hi = s;
      f_hi = fc;
      if (side == 1) f_lo *= 0.5;
      side = 1;
    }
    if (std::abs(fc) <= std::abs(best.lin.stab.lambda_min)) best = std::move(c);
  }
  if (s_hi - s_lo > s_tol && f_hi != 0.0) {
    res->message = "crossing not located to tolerance (bracket " +
                   std::to_string((s_hi - s_lo) / unit) + " rad)";
  }
  res->ok = res->message.empty();
  res->kind = fold ? RollInstability::kFold : RollInstability::kBifurcation;
  res->bracket_rad = (s_hi - s_lo) / unit;
  res->critical_roll_rad = best.roll;
  res->lambda_min = best.lin.stab.lambda_min;
  res->tangent_roll = best.tangent(P.N) / P.roll_weight;
  res->twist_moment = best.starts[0].m.dot(P.d3A);
  res->critical_mode = best.lin.stab.mode;
  res->shape = ShapeOf(P, best.starts, best.residual);
  res->max_hessian_asymmetry = std::max(res->max_hessian_asymmetry, best.lin.stab.asymmetry);
  if (direction * best.roll > range) {
    res->kind = RollInstability::kNoneInRange;
    res->message = "first loss of stability at roll " + std::to_string(best.roll) +
                   " rad, beyond the range";
    res->ok = true;
  } else if (res->ok) {
    res->message = std::string(RollInstabilityName(res->kind)) + " at roll " +
                   std::to_string(best.roll) + " rad";
  }
}

}  // namespace detail

// The critical roll of clamp A (see the top comment). clamp_b is the fixed end clamp
// (position, tangent, normal as EndCondition::Clamp). initial_guess = (n(0), m(0)) for the
// untwisted solve, which SolveKirchhoff does with `start_continuation_steps` homotopy steps
// (the loop needs one: e.g. the circle m(0) = 2 pi B / L about the loop's normal).
inline CriticalRollResult CriticalRoll(const RodProperties& props, const ClampSpec& clamp_a,
                                       const ClampSpec& clamp_b,
                                       const CriticalRollOptions& opts = {},
                                       const Eigen::Matrix<double, 6, 1>* initial_guess = nullptr) {
  CriticalRollResult res;
  std::string why;
  if (!opts.Check(&why)) {
    res.message = "CriticalRollOptions: " + why;
    return res;
  }
  // 1. The untwisted equilibrium.
  ShootingOptions so;
  so.steps = opts.steps;
  so.segments = opts.segments;
  so.continuation_steps = opts.start_continuation_steps;
  so.tolerance = opts.tolerance;
  res.untwisted = SolveKirchhoff(
      props, clamp_a, EndCondition::Clamp(clamp_b.position, clamp_b.tangent, clamp_b.normal), so,
      initial_guess);
  if (!res.untwisted.converged) {
    res.message = "untwisted equilibrium not found: " + res.untwisted.message;
    return res;
  }
  detail::RollProblem P;
  detail::SetUpRollProblem(props, clamp_a, clamp_b, opts, &P);
  const double direction = opts.max_roll_rad > 0 ? 1.0 : -1.0;
  detail::CurvePoint a = detail::RollStart(&P, res.untwisted, direction);
  detail::RecordPathPoint(P, a, &res);
  // Strictly stable start: lambda_min above the rounding of H's spectrum (a neutral mode, e.g.
  // a weightless loop turning about coaxial clamps, is not a start the roll can follow).
  const double spectrum = a.lin.stab.eigenvalues.cwiseAbs().maxCoeff();
  if (!(a.lin.stab.lambda_min > 1e-10 * spectrum)) {
    res.message = "the untwisted equilibrium is not stable (lambda_min " +
                  std::to_string(a.lin.stab.lambda_min) + " of a spectrum up to " +
                  std::to_string(spectrum) + ", index " + std::to_string(a.lin.stab.index) + ")";
    res.shape = res.untwisted;
    return res;
  }
  Eigen::PartialPivLU<Eigen::MatrixXd> chord = detail::ChordMatrix(P, a);
  detail::CurvePoint b;
  if (!detail::FollowRoll(P, opts, &a, &chord, &b, &res)) return res;
  detail::LocateCrossing(P, opts, a, chord, b, &res);
  return res;
}

}  // namespace rodfit_reference
