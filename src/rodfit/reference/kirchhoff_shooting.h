// Independent reference solver for the continuous Kirchhoff rod (header-only; Eigen 3 + C++17).
//
// MODEL AND CONVENTIONS. Arc length s in [0, L] is the reference (unstretched) arc length.
// State: centre-line r(s); material frame R(s) = [d1 d2 d3] stored as a unit quaternion q
// (R = R(q)); n(s), m(s) = force and moment (world frame) exerted ON the part [0, s] BY the
// part (s, L], moments taken about r(s). Equations (f = linear_density * gravity, uniform):
//     R' = R [u]x        (d_i' = w x d_i, w = R u, u = (k1, k2, tau) body curvatures)
//     u  = u_rest + K^-1 R^T m,  K = diag(B1, B2, GJ)          (m = R K (u - u_rest))
//     r' = (1 + n.d3 / EA) d3      (EA = +inf: inextensible, r' = d3)
//     n' = -f,     m' = -r' x n.
// With this sign convention a free end carries n(L) = applied force, m(L) = applied moment,
// the clamp at s = 0 exerts -n(0), -m(0) on the rod, and n(0) = n(L) + f L (total load).
// Clamp at s = 0: r(0) = p0, d3 = normalize(tangent), d1 = Gram-Schmidt(normal vs d3),
// d2 = d3 x d1. End conditions at s = L (EndCondition::Kind):
//     kFree           n(L) = F, m(L) = M (dead force and moment, world frame)
//     kFollower       n(L) = F, m(L) = R(L) mb (mb = `moment`, components in the end frame)
//     kClamp          r(L) = pL, R(L) = frame(tangentL, normalL)
//     kClampFreeTwist r(L) = pL, d3(L) = normalize(tangentL), m(L).d3(L) = 0
//     kPin            r(L) = pL, m(L) = 0
// NUMERICS. Classical RK4 on a uniform grid of `steps` steps (quaternion renormalised after
// each step; the exact flow preserves |q| = 1). Unknowns n(0), m(0) (6), plus, for multiple
// shooting with `segments` = K > 1, the full state (r, rotation, n, m: 12) at the start of each
// later segment, with 12 continuity residuals per interface (rotation mismatch measured by the
// quaternion log). Unknowns and residuals are non-dimensionalised by L, Bref = max(B1, B2):
// positions / L, forces * L^2 / Bref, moments * L / Bref, rotations in rad. Newton with a
// central finite-difference Jacobian, column-pivoting QR solve and backtracking on the residual
// 2-norm. Continuation (continuation_steps > 1) follows the Newton homotopy
//     H(x, lambda) = F(x; loads * lambda) - (1 - lambda) F(x0; loads * 0),  lambda: 0 -> 1,
// (loads are ramped only if ramp_loads) for which the initial guess x0 is an exact solution
// at lambda = 0. For prescribed-position ends this is a continuation of the end target from
// the end pose of the initial guess to the requested one. A failed continuation step is
// retried with half the increment. Multiple shooting is needed when single shooting is
// ill-conditioned (e.g. a long rod under strong gravity: exponential growth ~ exp(int sqrt(T/B))).
//
// API (namespace rodfit_reference):
//   struct RodProperties { length, B1, B2, GJ, EA, rest_curvature, linear_density, gravity };
//   struct ClampSpec { position, tangent, normal };
//   struct EndCondition { kind, force, moment, position, tangent, normal;
//                         static Free(F, M), Follower(F, mb), Clamp(p, t, n),
//                         ClampFreeTwist(p, t), Pin(p) };
//   struct ShootingOptions { steps, segments, max_newton, tolerance, continuation_tolerance,
//                            continuation_steps, ramp_loads, fd_step, max_halvings };
//   struct ShootingResult { converged, residual, newton_iterations, continuation_steps_taken,
//                           lambda, message, n0, m0, nL, mL, s, r, frames, n, m, tangent;
//                           RodState StateAt(s); Vector3d PositionAt(s); Matrix3d FrameAt(s) };
//   ShootingResult SolveKirchhoff(const RodProperties&, const ClampSpec&, const EndCondition&,
//                                 const ShootingOptions& = {},
//                                 const Eigen::Matrix<double, 6, 1>* initial_guess = nullptr);
//       initial_guess = (n(0), m(0)); default: n0 = F + f L for free/follower ends when not
//       continuing (exact), else zero; m0 = 0.
//   ShootingResult IntegrateFromClamp(props, clamp, n0, m0, steps): a single forward shot
//       (no end condition), for initial value tests.
//   Eigen::Matrix3d FrameFromTangentNormal(t, n);
// ACCURACY (tests/reference/kirchhoff_shooting_test.cc): with the default 4000 steps the closed-form helix
// (4 rad of precession) is reproduced to 6e-14 L and the 2 pi circle closes to 3e-15 L; the
// hanging loop and a cantilever at P L^2/EI = 10 change by < 1e-12 L between 4000 and 8000
// steps (RK4 error ~ 16/15 of that difference).
// StateAt / PositionAt / FrameAt take one RK4 step of size s - s_i from the grid node s_i <= s,
// so they are as accurate as the grid itself (local error O(h^5)), not an interpolation.
#pragma once

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfit_reference {

inline constexpr double kInfinity = std::numeric_limits<double>::infinity();

struct RodProperties {
  double length = 1.0;
  double B1 = 1.0;  // bending stiffness about d1 [N m^2]
  double B2 = 1.0;  // bending stiffness about d2
  double GJ = 1.0;  // torsional stiffness about d3
  double EA = kInfinity;  // axial stiffness [N]; infinity = inextensible
  Eigen::Vector3d rest_curvature = Eigen::Vector3d::Zero();  // (k1o, k2o, tauo) [1/m]
  double linear_density = 0.0;                              // [kg/m]
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();        // [m/s^2]
  Eigen::Vector3d DistributedForce() const { return linear_density * gravity; }
};

struct ClampSpec {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d tangent = Eigen::Vector3d::UnitX();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
};

struct EndCondition {
  enum Kind { kFree, kFollower, kClamp, kClampFreeTwist, kPin };
  Kind kind = kFree;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   // dead tip force (kFree, kFollower)
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();  // kFree: world; kFollower: end-frame comps
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // kClamp, kClampFreeTwist, kPin
  Eigen::Vector3d tangent = Eigen::Vector3d::UnitX();  // kClamp, kClampFreeTwist
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();   // kClamp

  static EndCondition Free(const Eigen::Vector3d& F, const Eigen::Vector3d& M) {
    EndCondition e;
    e.kind = kFree;
    e.force = F;
    e.moment = M;
    return e;
  }
  static EndCondition Follower(const Eigen::Vector3d& F, const Eigen::Vector3d& mb) {
    EndCondition e;
    e.kind = kFollower;
    e.force = F;
    e.moment = mb;
    return e;
  }
  static EndCondition Clamp(const Eigen::Vector3d& p, const Eigen::Vector3d& t,
                            const Eigen::Vector3d& nrm) {
    EndCondition e;
    e.kind = kClamp;
    e.position = p;
    e.tangent = t;
    e.normal = nrm;
    return e;
  }
  static EndCondition ClampFreeTwist(const Eigen::Vector3d& p, const Eigen::Vector3d& t) {
    EndCondition e;
    e.kind = kClampFreeTwist;
    e.position = p;
    e.tangent = t;
    return e;
  }
  static EndCondition Pin(const Eigen::Vector3d& p) {
    EndCondition e;
    e.kind = kPin;
    e.position = p;
    return e;
  }
};

struct ShootingOptions {
  int steps = 4000;        // RK4 steps over the whole length (split evenly between segments)
  int segments = 1;        // multiple-shooting segments; 1 = single shooting
  int max_newton = 100;    // Newton iterations per continuation step
  double tolerance = 1e-11;              // final scaled residual 2-norm
  double continuation_tolerance = 1e-8;  // intermediate continuation steps
  int continuation_steps = 1;            // 1 = solve directly at lambda = 1
  bool ramp_loads = true;  // scale gravity and end loads by lambda during continuation
  double fd_step = 1e-6;   // central finite-difference step in scaled unknowns
  int max_halvings = 16;   // a continuation increment may be halved this often in a row
};

struct RodState {
  Eigen::Vector3d r = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  Eigen::Matrix3d Frame() const { return q.toRotationMatrix(); }
};

// ---------------------------------------------------------------------------------------------
// Rotation helpers.

inline Eigen::Matrix3d FrameFromTangentNormal(const Eigen::Vector3d& tangent,
                                              const Eigen::Vector3d& normal) {
  const Eigen::Vector3d d3 = tangent.normalized();
  Eigen::Vector3d d1 = normal - normal.dot(d3) * d3;
  if (!(d1.norm() > 1e-12 * normal.norm())) {
    throw std::invalid_argument("FrameFromTangentNormal: normal parallel to tangent");
  }
  d1.normalize();
  Eigen::Matrix3d R;
  R.col(0) = d1;
  R.col(1) = d3.cross(d1);
  R.col(2) = d3;
  return R;
}

// exp: rotation vector -> unit quaternion.
inline Eigen::Quaterniond QuatExp(const Eigen::Vector3d& v) {
  const double th = v.norm();
  const double c = std::cos(0.5 * th);
  // sin(th/2)/th with its Taylor series near 0 (avoids 0/0).
  const double sc = th > 1e-6 ? std::sin(0.5 * th) / th : 0.5 - th * th / 48.0;
  return Eigen::Quaterniond(c, sc * v.x(), sc * v.y(), sc * v.z());
}

// log: unit quaternion -> rotation vector in (-pi, pi]; zero only for the identity rotation
// (so a residual built from it has no spurious zero at 180 degrees, unlike a cross product).
inline Eigen::Vector3d QuatLog(Eigen::Quaterniond q) {
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const double vn = q.vec().norm();
  if (vn < 1e-300) return Eigen::Vector3d::Zero();
  return (2.0 * std::atan2(vn, q.w()) / vn) * q.vec();
}

// ---------------------------------------------------------------------------------------------
// ODE right-hand side and RK4.

using StateVector = Eigen::Matrix<double, 13, 1>;  // r(0:3), q(w,x,y,z)(3:7), n(7:10), m(10:13)

inline StateVector Pack(const RodState& x) {
  StateVector y;
  y.segment<3>(0) = x.r;
  y(3) = x.q.w();
  y(4) = x.q.x();
  y(5) = x.q.y();
  y(6) = x.q.z();
  y.segment<3>(7) = x.n;
  y.segment<3>(10) = x.m;
  return y;
}

inline RodState Unpack(const StateVector& y) {
  RodState x;
  x.r = y.segment<3>(0);
  x.q = Eigen::Quaterniond(y(3), y(4), y(5), y(6)).normalized();
  x.n = y.segment<3>(7);
  x.m = y.segment<3>(10);
  return x;
}

// Unit tangent scale 1 + n.d3/EA (stretch of the centre-line).
inline double Stretch(const RodProperties& p, const Eigen::Vector3d& n,
                      const Eigen::Vector3d& d3) {
  return std::isfinite(p.EA) ? 1.0 + n.dot(d3) / p.EA : 1.0;
}

inline StateVector RodRhs(const RodProperties& p, const Eigen::Vector3d& f, const StateVector& y) {
  const Eigen::Quaterniond q(y(3), y(4), y(5), y(6));
  // Frame from the normalised quaternion so stages with |q| != 1 still use a rotation.
  const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
  const Eigen::Vector3d n = y.segment<3>(7);
  const Eigen::Vector3d m = y.segment<3>(10);
  const Eigen::Vector3d mb = R.transpose() * m;  // moment in the material frame
  const Eigen::Vector3d u =
      p.rest_curvature + Eigen::Vector3d(mb.x() / p.B1, mb.y() / p.B2, mb.z() / p.GJ);
  const Eigen::Vector3d d3 = R.col(2);
  const Eigen::Vector3d dr = Stretch(p, n, d3) * d3;
  StateVector dy;
  dy.segment<3>(0) = dr;
  // q' = 1/2 q (x) (0, u): body-frame angular velocity u, i.e. R' = R [u]x.
  dy(3) = -0.5 * q.vec().dot(u);
  dy.segment<3>(4) = 0.5 * (q.w() * u + q.vec().cross(u));
  dy.segment<3>(7) = -f;
  dy.segment<3>(10) = -dr.cross(n);
  return dy;
}

inline StateVector Rk4Step(const RodProperties& p, const Eigen::Vector3d& f, const StateVector& y,
                           double h) {
  const StateVector k1 = RodRhs(p, f, y);
  const StateVector k2 = RodRhs(p, f, y + 0.5 * h * k1);
  const StateVector k3 = RodRhs(p, f, y + 0.5 * h * k2);
  const StateVector k4 = RodRhs(p, f, y + h * k3);
  StateVector out = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  out.segment<4>(3).normalize();
  return out;
}

// Integrates [s0, s1] in `steps` uniform steps; optionally records every node (s0 included,
// s1 included only if record_last).
inline StateVector IntegrateSegment(const RodProperties& p, const Eigen::Vector3d& f,
                                    const StateVector& y0, double s0, double s1, int steps,
                                    std::vector<double>* s_out = nullptr,
                                    std::vector<StateVector>* y_out = nullptr,
                                    bool record_last = false) {
  const double h = (s1 - s0) / steps;
  StateVector y = y0;
  for (int i = 0; i < steps; ++i) {
    if (s_out) {
      s_out->push_back(s0 + i * h);
      y_out->push_back(y);
    }
    y = Rk4Step(p, f, y, h);
  }
  if (s_out && record_last) {
    s_out->push_back(s1);
    y_out->push_back(y);
  }
  return y;
}

// ---------------------------------------------------------------------------------------------
// Result.

struct ShootingResult {
  bool converged = false;
  double residual = kInfinity;  // scaled 2-norm of the residual at the final lambda
  int newton_iterations = 0;    // total over all continuation steps
  int continuation_steps_taken = 0;
  double lambda = 0.0;  // continuation parameter reached (1 on success)
  std::string message;
  Eigen::Vector3d n0 = Eigen::Vector3d::Zero(), m0 = Eigen::Vector3d::Zero();
  Eigen::Vector3d nL = Eigen::Vector3d::Zero(), mL = Eigen::Vector3d::Zero();
  // Samples on the RK4 grid (s increasing, s.front() = 0, s.back() = L).
  std::vector<double> s;
  std::vector<Eigen::Vector3d> r, n, m, tangent;  // tangent = r' (unit if inextensible)
  std::vector<Eigen::Matrix3d> frames;
  // For StateAt: the ODE data used for the samples.
  RodProperties props;
  Eigen::Vector3d distributed_force = Eigen::Vector3d::Zero();
  std::vector<StateVector> states;

  RodState StateAt(double sq) const {
    if (s.empty()) throw std::logic_error("ShootingResult::StateAt: no samples");
    sq = std::clamp(sq, s.front(), s.back());
    auto it = std::upper_bound(s.begin(), s.end(), sq);
    size_t i = (it == s.begin()) ? 0 : static_cast<size_t>(it - s.begin()) - 1;
    if (i + 1 >= s.size()) i = s.size() - 1;
    const double h = sq - s[i];
    if (h == 0.0) return Unpack(states[i]);
    // One RK4 step of size h <= grid step from the node below: as accurate as the grid.
    return Unpack(Rk4Step(props, distributed_force, states[i], h));
  }
  Eigen::Vector3d PositionAt(double sq) const { return StateAt(sq).r; }
  Eigen::Matrix3d FrameAt(double sq) const { return StateAt(sq).Frame(); }
};

inline void FillSamples(ShootingResult& res, const std::vector<double>& s,
                        const std::vector<StateVector>& ys) {
  res.s = s;
  res.states = ys;
  res.r.clear();
  res.n.clear();
  res.m.clear();
  res.tangent.clear();
  res.frames.clear();
  for (const StateVector& y : ys) {
    const RodState x = Unpack(y);
    res.r.push_back(x.r);
    res.n.push_back(x.n);
    res.m.push_back(x.m);
    const Eigen::Matrix3d R = x.Frame();
    res.frames.push_back(R);
    res.tangent.push_back(Stretch(res.props, x.n, R.col(2)) * R.col(2));
  }
}

inline RodState ClampState(const ClampSpec& c) {
  RodState x;
  x.r = c.position;
  x.q = Eigen::Quaterniond(FrameFromTangentNormal(c.tangent, c.normal)).normalized();
  return x;
}

// Single forward shot from the clamp with given n(0), m(0); no end condition is imposed.
inline ShootingResult IntegrateFromClamp(const RodProperties& p, const ClampSpec& clamp,
                                         const Eigen::Vector3d& n0, const Eigen::Vector3d& m0,
                                         int steps = 4000) {
  ShootingResult res;
  res.props = p;
  res.distributed_force = p.DistributedForce();
  RodState x0 = ClampState(clamp);
  x0.n = n0;
  x0.m = m0;
  std::vector<double> s;
  std::vector<StateVector> ys;
  const StateVector yL =
      IntegrateSegment(p, res.distributed_force, Pack(x0), 0.0, p.length, steps, &s, &ys, true);
  FillSamples(res, s, ys);
  res.n0 = n0;
  res.m0 = m0;
  res.nL = yL.segment<3>(7);
  res.mL = yL.segment<3>(10);
  res.converged = true;
  res.residual = 0.0;
  res.lambda = 1.0;
  return res;
}

// ---------------------------------------------------------------------------------------------
// Shooting machinery.

namespace detail {

struct Shooter {
  RodProperties p;
  EndCondition end;
  ShootingOptions o;
  RodState clamp0;
  int K = 1;
  std::vector<double> sb;  // segment boundaries, size K + 1
  std::vector<int> nst;    // RK4 steps per segment
  double L = 1, Fs = 1, Ms = 1;
  Eigen::Quaterniond q_end = Eigen::Quaterniond::Identity();  // kClamp target
  Eigen::Vector3d t_end = Eigen::Vector3d::UnitX(), e1 = Eigen::Vector3d::UnitY(),
                  e2 = Eigen::Vector3d::UnitZ();  // kClampFreeTwist target and its normals
  int N = 6;

  double LoadScale(double lambda) const { return o.ramp_loads ? lambda : 1.0; }

  int Col0(int k) const { return k == 0 ? 0 : 6 + 12 * (k - 1); }

  RodState IntegrateSeg(const RodState& start, int k, double load_scale) const {
    const Eigen::Vector3d f = load_scale * p.DistributedForce();
    return Unpack(IntegrateSegment(p, f, Pack(start), sb[k], sb[k + 1], nst[k]));
  }

  std::vector<RodState> IntegrateAll(const std::vector<RodState>& starts, double ls) const {
    std::vector<RodState> ends(K);
    for (int k = 0; k < K; ++k) ends[k] = IntegrateSeg(starts[k], k, ls);
    return ends;
  }

  // Scaled residual F(x; loads * ls): continuity blocks then the 6 end residuals.
  Eigen::VectorXd Assemble(const std::vector<RodState>& starts, const std::vector<RodState>& ends,
                           double ls) const {
    Eigen::VectorXd F(N);
    for (int k = 0; k + 1 < K; ++k) {
      const RodState& a = ends[k];
      const RodState& b = starts[k + 1];
      F.segment<3>(12 * k) = (a.r - b.r) / L;
      F.segment<3>(12 * k + 3) = QuatLog(b.q.conjugate() * a.q);
      F.segment<3>(12 * k + 6) = (a.n - b.n) / Fs;
      F.segment<3>(12 * k + 9) = (a.m - b.m) / Ms;
    }
    const RodState& e = ends[K - 1];
    const int r0 = 12 * (K - 1);
    const Eigen::Matrix3d R = e.Frame();
    switch (end.kind) {
      case EndCondition::kFree:
        F.segment<3>(r0) = (e.n - ls * end.force) / Fs;
        F.segment<3>(r0 + 3) = (e.m - ls * end.moment) / Ms;
        break;
      case EndCondition::kFollower:
        F.segment<3>(r0) = (e.n - ls * end.force) / Fs;
        F.segment<3>(r0 + 3) = (e.m - ls * (R * end.moment)) / Ms;
        break;
      case EndCondition::kClamp:
        F.segment<3>(r0) = (e.r - end.position) / L;
        F.segment<3>(r0 + 3) = QuatLog(q_end.conjugate() * e.q);
        break;
      case EndCondition::kClampFreeTwist:
        F.segment<3>(r0) = (e.r - end.position) / L;
        F(r0 + 3) = R.col(2).dot(e1);
        F(r0 + 4) = R.col(2).dot(e2);
        F(r0 + 5) = e.m.dot(R.col(2)) / Ms;
        break;
      case EndCondition::kPin:
        F.segment<3>(r0) = (e.r - end.position) / L;
        F.segment<3>(r0 + 3) = e.m / Ms;
        break;
    }
    return F;
  }

  // Perturbs scaled unknown j of segment k by d.
  void Perturb(RodState& x, int k, int j, double d) const {
    if (k == 0) {
      if (j < 3) x.n(j) += d * Fs;
      else x.m(j - 3) += d * Ms;
      return;
    }
    if (j < 3) x.r(j) += d * L;
    else if (j < 6) x.q = (x.q * QuatExp(d * Eigen::Vector3d::Unit(j - 3))).normalized();
    else if (j < 9) x.n(j - 6) += d * Fs;
    else x.m(j - 9) += d * Ms;
  }

  std::vector<RodState> Apply(const std::vector<RodState>& starts, const Eigen::VectorXd& dz,
                              double alpha) const {
    std::vector<RodState> out = starts;
    out[0].n += alpha * Fs * dz.segment<3>(0);
    out[0].m += alpha * Ms * dz.segment<3>(3);
    for (int k = 1; k < K; ++k) {
      const int c = Col0(k);
      out[k].r += alpha * L * dz.segment<3>(c);
      out[k].q = (out[k].q * QuatExp(alpha * dz.segment<3>(c + 3))).normalized();
      out[k].n += alpha * Fs * dz.segment<3>(c + 6);
      out[k].m += alpha * Ms * dz.segment<3>(c + 9);
    }
    return out;
  }

  // Central finite differences; perturbing segment k re-integrates only segment k.
  Eigen::MatrixXd Jacobian(const std::vector<RodState>& starts, const std::vector<RodState>& ends,
                           double ls) const {
    Eigen::MatrixXd J(N, N);
    const double h = o.fd_step;
    for (int k = 0; k < K; ++k) {
      const int nv = (k == 0) ? 6 : 12;
      for (int j = 0; j < nv; ++j) {
        Eigen::VectorXd Fpm[2];
        for (int sgn = 0; sgn < 2; ++sgn) {
          std::vector<RodState> st = starts;
          std::vector<RodState> en = ends;
          Perturb(st[k], k, j, sgn == 0 ? h : -h);
          en[k] = IntegrateSeg(st[k], k, ls);
          Fpm[sgn] = Assemble(st, en, ls);
        }
        J.col(Col0(k) + j) = (Fpm[0] - Fpm[1]) / (2.0 * h);
      }
    }
    return J;
  }

  Eigen::VectorXd H(const std::vector<RodState>& starts, double lambda,
                    const Eigen::VectorXd& F0, std::vector<RodState>* ends_out = nullptr) const {
    const double ls = LoadScale(lambda);
    std::vector<RodState> ends = IntegrateAll(starts, ls);
    Eigen::VectorXd F = Assemble(starts, ends, ls) - (1.0 - lambda) * F0;
    if (ends_out) *ends_out = std::move(ends);
    return F;
  }

  // Damped Newton at fixed lambda. Returns true if |H| < tol.
  bool Newton(std::vector<RodState>& starts, double lambda, const Eigen::VectorXd& F0, double tol,
              int* iterations, double* res_norm) const {
    std::vector<RodState> ends;
    Eigen::VectorXd F = H(starts, lambda, F0, &ends);
    double norm = F.norm();
    for (int it = 0;; ++it) {
      if (!std::isfinite(norm)) break;
      if (norm < tol) {
        *res_norm = norm;
        return true;
      }
      if (it >= o.max_newton) break;
      ++*iterations;
      const Eigen::MatrixXd J = Jacobian(starts, ends, LoadScale(lambda));
      const Eigen::VectorXd dz = J.colPivHouseholderQr().solve(-F);
      if (!dz.allFinite()) break;
      // Backtracking (Armijo on the residual norm).
      bool accepted = false;
      for (double alpha = 1.0; alpha > 1e-10; alpha *= 0.5) {
        std::vector<RodState> trial = Apply(starts, dz, alpha);
        std::vector<RodState> trial_ends;
        const Eigen::VectorXd Ft = H(trial, lambda, F0, &trial_ends);
        const double nt = Ft.norm();
        if (std::isfinite(nt) && nt <= (1.0 - 1e-4 * alpha) * norm) {
          starts = std::move(trial);
          ends = std::move(trial_ends);
          F = Ft;
          norm = nt;
          accepted = true;
          break;
        }
      }
      if (!accepted) break;  // no descent: stalled (at the rounding floor or a bad guess)
    }
    *res_norm = norm;
    return norm < tol;
  }
};

// The shooter of `props` from `clamp` to `end`: opts.segments segments of equal length, the
// scales of the residual's forces and moments, the end's target frame.
inline void SetUpShooter(const RodProperties& props, const ClampSpec& clamp,
                         const EndCondition& end, const ShootingOptions& opts, Shooter* S) {
  S->p = props;
  S->end = end;
  S->o = opts;
  S->clamp0 = ClampState(clamp);
  S->K = std::max(1, opts.segments);
  S->L = props.length;
  const double Bref = std::max(props.B1, props.B2);
  S->Fs = Bref / (S->L * S->L);
  S->Ms = Bref / S->L;
  S->N = 6 + 12 * (S->K - 1);
  const int steps_per_seg = std::max(1, (opts.steps + S->K - 1) / S->K);
  for (int k = 0; k <= S->K; ++k) S->sb.push_back(S->L * k / S->K);
  S->sb.back() = S->L;
  S->nst.assign(S->K, steps_per_seg);
  if (end.kind == EndCondition::kClamp) {
    S->q_end = Eigen::Quaterniond(FrameFromTangentNormal(end.tangent, end.normal)).normalized();
  }
  if (end.kind == EndCondition::kClampFreeTwist) {
    S->t_end = end.tangent.normalized();
    // Any orthonormal pair perpendicular to the target tangent.
    S->e1 = S->t_end.unitOrthogonal();
    S->e2 = S->t_end.cross(S->e1);
  }
}

// The initial guess for (n0, m0) and, by one forward shot at load scale ls0, for the segment
// start states. `cont`: the homotopy's steps (1: none).
inline std::vector<RodState> FirstStarts(const Shooter& S, const RodProperties& props,
                                         const EndCondition& end,
                                         const Eigen::Matrix<double, 6, 1>* initial_guess,
                                         int cont, double ls0) {
  Eigen::Vector3d n0 = Eigen::Vector3d::Zero(), m0 = Eigen::Vector3d::Zero();
  if (initial_guess) {
    n0 = initial_guess->head<3>();
    m0 = initial_guess->tail<3>();
  } else if ((end.kind == EndCondition::kFree || end.kind == EndCondition::kFollower) &&
             cont == 1) {
    n0 = end.force + props.length * props.DistributedForce();  // exact total load
  }
  std::vector<RodState> starts(S.K);
  starts[0] = S.clamp0;
  starts[0].n = n0;
  starts[0].m = m0;
  for (int k = 1; k < S.K; ++k) starts[k] = S.IntegrateSeg(starts[k - 1], k - 1, ls0);
  return starts;
}

// Newton at lambda = 1 (cont == 1), or the homotopy from F0 in `cont` steps of lambda, a failed
// step halved (at most opts.max_halvings times in a row). Counts the Newton iterations and steps
// in res; *lambda, *norm: the lambda reached and its residual. True: converged at lambda = 1.
inline bool Continue(const Shooter& S, const ShootingOptions& opts, int cont,
                     const Eigen::VectorXd& F0, std::vector<RodState>* starts_io,
                     ShootingResult* res, double* lambda_out, double* norm_out) {
  std::vector<RodState>& starts = *starts_io;
  double lambda = (cont > 1) ? 0.0 : 1.0;
  double dlambda = 1.0 / cont;
  int halvings = 0;
  double norm = kInfinity;
  bool ok = false;
  if (cont == 1) {
    ok = S.Newton(starts, 1.0, F0, opts.tolerance, &res->newton_iterations, &norm);
    res->continuation_steps_taken = 1;
  } else {
    while (lambda < 1.0) {
      const double lt = std::min(1.0, lambda + dlambda);
      const bool last = (lt >= 1.0);
      std::vector<RodState> trial = starts;
      double nt = kInfinity;
      const bool step_ok = S.Newton(trial, lt, F0,
                                    last ? opts.tolerance : opts.continuation_tolerance,
                                    &res->newton_iterations, &nt);
      if (step_ok) {
        starts = std::move(trial);
        lambda = lt;
        norm = nt;
        ++res->continuation_steps_taken;
        halvings = 0;
        ok = last;
        dlambda = std::min(2.0 * dlambda, 1.0 / cont);  // recover the nominal increment
      } else if (last && nt < opts.continuation_tolerance) {
        // Stalled just above the final tolerance (rounding floor): keep it, flag it.
        starts = std::move(trial);
        lambda = lt;
        norm = nt;
        ++res->continuation_steps_taken;
        break;
      } else {
        norm = nt;
        if (++halvings > opts.max_halvings) break;
        dlambda *= 0.5;
      }
    }
  }
  *lambda_out = lambda;
  *norm_out = norm;
  return ok;
}

// The samples of the solution from `starts` at the reached lambda, its end forces and moments,
// and whether (and why not) it converged.
inline void FillShootingResult(const Shooter& S, const RodProperties& props,
                               const EndCondition& end, const std::vector<RodState>& starts,
                               double lambda, double norm, bool ok, ShootingResult* res) {
  res->lambda = lambda;
  res->residual = norm;
  const double ls = S.LoadScale(lambda);
  res->distributed_force = ls * props.DistributedForce();
  std::vector<double> s;
  std::vector<StateVector> ys;
  StateVector yL = StateVector::Zero();
  for (int k = 0; k < S.K; ++k) {
    yL = IntegrateSegment(props, res->distributed_force, Pack(starts[k]), S.sb[k], S.sb[k + 1],
                          S.nst[k], &s, &ys, k == S.K - 1);
  }
  FillSamples(*res, s, ys);
  res->n0 = starts[0].n;
  res->m0 = starts[0].m;
  res->nL = yL.segment<3>(7);
  res->mL = yL.segment<3>(10);
  res->converged = ok && lambda >= 1.0;
  if (res->converged && end.kind == EndCondition::kClampFreeTwist &&
      res->frames.back().col(2).dot(S.t_end) <= 0.0) {
    res->converged = false;  // spurious root d3(L) = -tangent
    res->message = "converged to d3(L) = -tangent";
  }
  if (res->message.empty()) {
    res->message = res->converged ? "converged"
                                  : "not converged (lambda " + std::to_string(lambda) +
                                        ", residual " + std::to_string(norm) + ")";
  }
}

}  // namespace detail

inline ShootingResult SolveKirchhoff(const RodProperties& props, const ClampSpec& clamp,
                                     const EndCondition& end, const ShootingOptions& opts = {},
                                     const Eigen::Matrix<double, 6, 1>* initial_guess = nullptr) {
  detail::Shooter S;
  detail::SetUpShooter(props, clamp, end, opts, &S);
  const int cont = std::max(1, opts.continuation_steps);
  const double ls0 = S.LoadScale(cont > 1 ? 0.0 : 1.0);
  std::vector<RodState> starts = detail::FirstStarts(S, props, end, initial_guess, cont, ls0);

  ShootingResult res;
  res.props = props;
  Eigen::VectorXd F0 = Eigen::VectorXd::Zero(S.N);
  if (cont > 1) F0 = S.Assemble(starts, S.IntegrateAll(starts, S.LoadScale(0.0)), S.LoadScale(0.0));
  double lambda = 0.0, norm = kInfinity;
  const bool ok = detail::Continue(S, opts, cont, F0, &starts, &res, &lambda, &norm);
  detail::FillShootingResult(S, props, end, starts, lambda, norm, ok, &res);
  return res;
}

}  // namespace rodfit_reference
