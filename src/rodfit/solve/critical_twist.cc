// The critical twist of a clamped rod (critical_twist.h; docs/solvers.md, "Critical twist").
//
// Path. The unknowns are the free dofs q and the roll r of clamp A about its tangent: the state's
// clamp frame is (t0, cos r d1_0 + sin r t0 x d1_0), and its reference twist at vertex 0 is
// unwrapped near the previous one, so the state keeps count of whole turns while r grows by
// small steps. The equilibrium g(q, r) = 0 (g the gradient of Pi over the free dofs, held rows
// zero) is followed in two phases:
//  1. natural steps in r while the branch is a minimum: the tangent predictor
//     q + dr dq/dr, dq/dr = -H^-1 dg/dr, then SolveStatics with the clamp at the new roll (the
//     one minimizer, saddles reported, not left). A step is retried at half the length when its
//     solve fails, its state is not stable, or it jumped to another branch (farther from the
//     predictor than kJumpFraction of the predictor's own move). The steps shorten as the
//     smallest eigenvalue lambda falls: each covers at most kCrossingFraction of the distance to
//     the crossing predicted by extrapolating lambda linearly in r (a bifurcation's) or lambda^2
//     (a fold's, where lambda ~ sqrt(r_f - r)), whichever predicted the last point better.
//  2. pseudo-arclength steps once the crossing predicted by extrapolating lambda linearly is
//     nearer than kArclengthTakeover (or the natural steps shrank below min_step_rad): unknowns
//     z = (q, r), the corrector solves g = 0 with t . W (z - z_a) = ds (W the continuation
//     metric below, t the unit tangent at the base z_a) as a Newton problem on the one minimizer
//     (ArclengthProblem), through a fold onto the unstable branch beyond it. Once lambda <= 0
//     at a corrected point, the crossing is bracketed on the arclength from the last base and
//     refined by secant steps kept inside the bracket (bisection when one leaves it), each
//     evaluation a corrector solve from the base, until a step is below locate_tolerance_rad.
//     The kind is a fold when the tangent's roll component changes sign across the bracket.
//
// Stability. lambda is the smallest eigenvalue of H v = lambda M v on the free dofs, H the
// assembled Hessian (held rows identity, excluded by keeping every vector zero there), M the
// lumped length metric (Voronoi length per position, edge length cubed per twist angle: a
// twist counts like the displacement it makes across an edge, so the twist modes, which never
// go unstable, stay far above the bending modes that do), so that the critical lambda
// converges with the segments. It is found by subspace inverse iteration with kModes vectors (a
// rod symmetric about its axis has a double critical eigenvalue, Greenhill's) and the banded
// Cholesky factor of H - sigma M, sigma below lambda (0 on the stable branch, a margin below it
// beyond the crossing), warm-started from the previous point, and its Ritz values are recomputed
// from the energy's terms one by one (QuadraticForms: the assembled band's round-off would swamp
// a soft mode's eigenvalue).
//
// Derivatives (CriticalTwistDerivatives). dg/dr is exact: rolling the clamp turns the ghost
// edge's d1, i.e. its twist angle theta_e in vertex 0's stencil, whose closed-form gradient is
// differentiated by a Jet (a clamp frame turned about any axis likewise moves the ghost edge's
// far vertex and theta_e). A stiffness's dg/dlog p is the gradient of its unit term (U is
// linear in each), the linear density's the weights' part of the dead loads.
//  - Fold: the extended system g = 0, H v = 0 gives H dq + g_r dr + g_p dp = 0, and with v^T:
//    dr_c/dp = -(v . g_p) / (v . g_r).
//  - Bifurcation: lambda(q(t), t) = 0 along the path, dlambda/dt = v^T (dH/dt) v with dH/dt the
//    Hessian's change along the path's tangent (dq/dt = -H^+ g_t, the null space projected out)
//    and the parameter's own unit-term Hessian; dr_c/dp = -(dlambda/dp) / (dlambda/dr). The
//    state's (and clamps') motion enters by fourth-order central differences of the assembled
//    Hessian: moved along the path's tangent the state stays an equilibrium to second order, so
//    the chart of the moved state (its reference frames) does not enter the first derivative.
#include "rodfit/solve/critical_twist.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <ceres/jet.h>

#include "rodfit/model/vertex_stencil.h"
#include "rodfit/solve/banded.h"
#include "rodfit/solve/newton_minimizer.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/rod_problem.h"
#include "rodfit/solve/sensitivity.h"

namespace rodfit {

const char* TwistInstabilityName(TwistInstability kind) {
  switch (kind) {
    case TwistInstability::kBifurcation: return "bifurcation";
    case TwistInstability::kFold: return "fold";
    case TwistInstability::kNoneInRange: return "none in range";
  }
  return "?";
}

bool CriticalTwistOptions::Check(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!std::isfinite(max_roll_rad) || max_roll_rad == 0.0)
    return fail("max_roll_rad must be finite and nonzero");
  if (!(min_step_rad > 0 && initial_step_rad >= min_step_rad && max_step_rad >= initial_step_rad))
    return fail("need 0 < min_step_rad <= initial_step_rad <= max_step_rad");
  if (!(locate_tolerance_rad > 0)) return fail("locate_tolerance_rad must be > 0");
  if (max_steps < 1 || max_locate_iterations < 1) return fail("iteration caps must be >= 1");
  std::string statics_why;
  if (!statics.Check(&statics_why)) {
    if (why) *why = "statics: " + statics_why;
    return false;
  }
  return true;
}

std::string CriticalTwistResult::BriefReport() const {
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "%s: %s at roll %.10g rad (%.4f deg), lambda_min %.3e (unit %.3e), %d natural + "
                "%d arclength steps (%d retried), %d locate iterations, %d Newton iterations, "
                "%.3f s: %s",
                ok ? "ok" : "FAILED", TwistInstabilityName(kind), critical_roll_rad,
                critical_roll_rad * 180.0 / M_PI, lambda_min, lambda_unit, natural_steps,
                arclength_steps, failed_steps, locate_iterations, newton_iterations, seconds,
                message.c_str());
  return buf;
}

namespace {

// The constants of the search, each with its reason.
/// Subspace of the inverse iteration: a rod symmetric about its axis has a double critical
/// eigenvalue; the vectors beyond it set the convergence rate (lambda_1 / lambda_7 per
/// iteration).
constexpr int kModes = 6;
/// Of which this many start from fixed vectors at every point (see LowestModes).
constexpr int kFreshModes = 2;
/// The Ritz values have converged when the lowest two change by less than this times the
/// subspace's spectral width (its largest Ritz value - sigma) in an iteration.
constexpr double kRitzTolerance = 1e-14;
constexpr int kMaxEigenIterations = 400;
/// Eigenvalues within this times lambda_unit of lambda_min count as one multiple eigenvalue.
constexpr double kMultipleEigenvalue = 1e-6;
/// The untwisted equilibrium must have lambda_min above this times lambda_unit: below it, the
/// smallest eigenvalue is the remnant of a neutral mode (a weightless loop turning about
/// coaxial clamps: 2.5e-6 lambda_unit at 30 segments, and of either sign once rolled), and
/// there is no branch to follow. A loop's turning mode is held by its weight, lambda ~ 5
/// (rho g L^3 / B) lambda_unit (the heavy loop of the tests: 780 lambda_unit), so only a loop
/// whose weight is ~1e-5 of its stiffness is refused.
constexpr double kStrictlyStable = 1e-4;
/// A natural step covers at most this fraction of the distance to the predicted crossing.
constexpr double kCrossingFraction = 0.6;
/// [rad] the pseudo-arclength phase takes over within this (linearly predicted) distance.
constexpr double kArclengthTakeover = 0.02;
/// A natural step jumped when its solution is farther from the predictor than this fraction of
/// the predictor's own move and than kJumpFloor x L.
constexpr double kJumpFraction = 0.5;
constexpr double kJumpFloor = 0.01;
/// The corrector's gradient tolerance (times the load scale) and step tolerance (times L on
/// positions, rad on angles and roll): near round-off, so that they do not limit the location.
constexpr double kCorrectorTolerance = 1e-12;
constexpr double kCorrectorStep = 1e-10;
constexpr int kCorrectorIterations = 8;
/// A corrector whose solution is farther from its predictor than this fraction of the arclength
/// step went somewhere else (the chord to another part of the curve).
constexpr double kCorrectorJump = 0.5;
/// A parameter's load overlapping the critical mode by more than this (relative) breaks a
/// bifurcation's symmetry (CriticalTwistDerivatives); a symmetric one overlaps by round-off.
constexpr double kSymmetryBroken = 1e-8;
/// [rad] the largest tangent turn of the fourth-order differences of the assembled Hessian.
constexpr double kDifferenceTurn = 1e-2;
/// The smallest arclength step [rad] before the continuation has stalled.
constexpr double kMinArclengthStep = 1e-12;

using Mat3 = Eigen::Matrix3d;

Mat3 RotationOf(const Vec3& rotation_vector) {
  const double a = rotation_vector.norm();
  if (a == 0.0) return Mat3::Identity();
  return Eigen::AngleAxisd(a, rotation_vector / a).toRotationMatrix();
}

Mat3 Hat(const Vec3& v) {
  Mat3 m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// d1 of clamp A rolled by `roll` about t from d1_0.
Vec3 RolledD1(const Vec3& t, const Vec3& d1_0, double roll) {
  return std::cos(roll) * d1_0 + std::sin(roll) * t.cross(d1_0);
}

// Sets clamp A's frame and recomputes the reference twists, unwrapped near the state's own
// (the roll's whole turns are kept in the reference twist at vertex 0).
bool SetClampFrame(const RodModel& model, const Vec3& t, const Vec3& d1, RodState* s) {
  s->clamp_t = t;
  s->clamp_d1 = d1;
  return UpdateReferenceFrames(model, *s, s);
}

// The model with clamp A rolled: SolveStatics moves a state's clamp to its model's, so each
// natural step solves on the model whose clamp is the state's.
RodModel RolledModel(const RodModel& model, const Vec3& d1) {
  LoadCase c = model.load_case();
  c.clamp.position = model.clamp_position();
  c.clamp.tangent = model.clamp_tangent();
  c.clamp.normal = d1;
  c.start = StartShape();
  std::vector<SpringZone> zones;
  for (int z = 0; z < model.num_spring_zones(); ++z) zones.push_back(model.spring_zone(z));
  return RodModel(model.rod(), model.material(), model.gravity(), c, zones);
}

// The lumped length metric M (see the top comment); held rows 1.
VecX LengthMetric(const RodModel& model) {
  const int n = model.num_edges();
  VecX m = VecX::Ones(model.num_free_dofs());
  for (int i = 1; i <= n; ++i) {
    const double cell =
        0.5 * (model.rest_edge_length(i - 1) + (i < n ? model.rest_edge_length(i) : 0.0));
    m.segment<3>(RodModel::VertexDof(i)).setConstant(cell);
  }
  for (int j = 0; j < n; ++j) m[RodModel::TwistDof(j)] = std::pow(model.rest_edge_length(j), 3);
  if (model.has_end_ghost()) m[RodModel::TwistDof(n)] = std::pow(model.end_ghost_length(), 3);
  return m;
}

double LambdaUnit(const RodModel& model) {
  const Material& m = model.material();
  const double L = model.length();
  return std::min({m.B1(), m.B2(), m.twist_stiffness}) / (L * L * L * L);
}

// V^T H V at a state with fresh frames, summed term by term: each vertex stencil's edge-variable
// Hessian (the one the assembly adds up) on the stencil's edge differences and twists, each
// edge's stretch as EA / l0 [(t . dv)(t . dw) + (1 - l0 / |e|)(dv . dw - (t . dv)(t . dw))],
// and the springs. The assembled band, multiplied out, is the same form, but there every row
// adds its edges' stretch terms EA / l0 t t^T (dv) before the product, whose round-off,
// ~eps EA / l0 per row, swamps a soft mode's eigenvalue (the bending stiffness B / l^3 is some
// 1e8 smaller on a realistic rod): here a soft mode's stretch term is the square of its small
// stretch, and the form is as exact as its own terms.
// `terms` selects and scales the stiffness terms as in the assembly (EnergyTerms; loads, linear
// in the state, have none).
Eigen::MatrixXd QuadraticForms(const RodModel& model, const RodState& s, const Eigen::MatrixXd& V,
                               const EnergyTerms& terms = EnergyTerms()) {
  const int n = model.num_edges();
  const int k = static_cast<int>(V.cols());
  Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(k, k);
  auto displacement = [&](int vertex, int c) -> Vec3 {
    if (vertex < 1 || vertex > n + (model.has_end_ghost() ? 1 : 0)) return Vec3::Zero();
    return V.col(c).segment<3>(RodModel::VertexDof(vertex));
  };
  auto twist = [&](int edge, int c) -> double {
    return edge < 0 ? 0.0 : V(RodModel::TwistDof(edge), c);
  };
  double q[11], g8[8], H8[64];
  VertexStencilConstants constants;
  std::array<int, 11> dof;
  Eigen::MatrixXd u(8, k);
  for (int i = 0; i < NumBendingVertices(model) && terms.AnyBendTwist(); ++i) {
    GatherVertexStencil(model, s, i, q, &constants, &dof);
    constants.B1 *= terms.bend1;
    constants.B2 *= terms.bend2;
    constants.GJ *= terms.twist;
    VertexHessianEdges(constants, q, g8, H8);
    for (int c = 0; c < k; ++c) {
      // The ghost behind the clamp and x_0 do not move; an end clamp's ghost vertex and x_n
      // are held (zero rows of V).
      const Vec3 prev = i >= 1 ? displacement(i - 1, c) : Vec3::Zero();
      const Vec3 mid = displacement(i, c), next = displacement(i + 1, c);
      u.col(c).segment<3>(0) = mid - prev;
      u.col(c).segment<3>(3) = next - mid;
      u(6, c) = twist(i - 1, c);
      u(7, c) = i < n ? twist(i, c) : V(RodModel::TwistDof(n), c);
    }
    const Eigen::Map<const Eigen::Matrix<double, 8, 8, Eigen::RowMajor>> H(H8);
    Q += u.transpose() * H * u;
  }
  const double EA = terms.stretch * model.material().stretch_stiffness;
  for (int j = 0; j < n && EA != 0.0; ++j) {
    const Vec3 e = s.e.col(j);
    const double len = e.norm(), l0 = model.rest_edge_length(j);
    const Vec3 t = e / len;
    for (int a = 0; a < k; ++a) {
      const Vec3 da = displacement(j + 1, a) - displacement(j, a);
      for (int b = a; b < k; ++b) {
        const Vec3 db = displacement(j + 1, b) - displacement(j, b);
        const double ta = t.dot(da), tb = t.dot(db);
        const double form = (EA / l0) * (ta * tb + (1.0 - l0 / len) * (da.dot(db) - ta * tb));
        Q(a, b) += form;
        if (b != a) Q(b, a) += form;
      }
    }
  }
  for (int z = 0; z < model.num_spring_zones() && terms.springs != 0.0; ++z) {
    if (terms.spring_parameter && model.spring_zone(z).parameter != *terms.spring_parameter)
      continue;
    const double K = terms.springs * model.zone_stiffness(z);
    for (int i = 1; i <= n; ++i) {
      const double kc = K * model.zone_cell_length(z, i);
      if (kc == 0.0) continue;
      for (int a = 0; a < k; ++a)
        for (int b = 0; b < k; ++b) Q(a, b) += kc * displacement(i, a).dot(displacement(i, b));
    }
  }
  return 0.5 * (Q + Q.transpose());
}

// The lowest kModes eigenpairs of H v = lambda M v on the free dofs.
struct Modes {
  VecX values;              // ascending
  Eigen::MatrixXd vectors;  // columns M-orthonormal, zero on held rows
  double shift = 0.0;       // the sigma whose factor was used
  int iterations = 0;
};

// Subspace inverse iteration with the banded Cholesky factor of H - sigma M, sigma from
// `shift` down (by `scale`, doubling) until it factors; warm-started from modes->vectors when
// they have the size. False when no shift factors or the iteration does not converge.
bool LowestModes(const RodModel& model, const RodState& state, const BandedSymmetric& H,
                 const VecX& metric, const std::vector<char>& held, double shift, double scale,
                 Modes* modes) {
  const int n = H.size();
  BandedSymmetric A;
  BandedCholesky chol;
  double sigma = shift, decrement = std::max(std::abs(shift), scale);
  bool factored = false;
  for (int k = 0; k < 200 && !factored; ++k) {
    A = H;
    for (int i = 0; i < n; ++i)
      if (!held[i]) A.At(i, i) -= sigma * metric[i];
    factored = chol.Factor(A);
    if (!factored) {
      sigma -= decrement;
      decrement *= 2.0;
    }
  }
  if (!factored) return false;
  modes->shift = sigma;
  // The start: the previous point's lowest vectors (warm), and fixed vectors with smooth and
  // rough components in every symmetry class (no random state) in the last kFreshModes columns:
  // a mode that crosses below from a class the warm vectors lack (in-plane and out-of-plane
  // modes of a planar loop do not mix) would never enter a warm subspace.
  Eigen::MatrixXd V(n, kModes);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < kModes; ++c)
      V(i, c) = std::sin(0.37 * (i + 1) * (c + 1) + 0.1 * c) + 0.5 * std::cos(0.011 * i * (c + 2));
  if (modes->vectors.rows() == n && modes->vectors.cols() == kModes)
    V.leftCols(kModes - kFreshModes) = modes->vectors.leftCols(kModes - kFreshModes);
  for (int i = 0; i < n; ++i)
    if (held[i]) V.row(i).setZero();
  Eigen::MatrixXd Y, MV;
  double previous0 = 0.0, previous1 = 0.0;
  for (int it = 1; it <= kMaxEigenIterations; ++it) {
    MV = metric.asDiagonal() * V;
    for (int i = 0; i < n; ++i)
      if (held[i]) MV.row(i).setZero();
    Y = MV;
    chol.SolveInPlace(Y);
    // Rayleigh–Ritz for A = H - sigma M on span(Y) with A Y = M V: Y^T A Y = Y^T M V, which
    // never multiplies by H (whose stretch entries, EA / l against B / l^3, would add their
    // round-off to the soft eigenvalues).
    Eigen::MatrixXd Ar = Y.transpose() * MV;
    Ar = 0.5 * (Ar + Ar.transpose()).eval();
    Eigen::MatrixXd Mr = Y.transpose() * metric.asDiagonal() * Y;
    Mr = 0.5 * (Mr + Mr.transpose()).eval();
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> ges(Ar, Mr);
    if (ges.info() != Eigen::Success) return false;
    V = Y * ges.eigenvectors();
    modes->values = ges.eigenvalues().array() + sigma;
    modes->iterations = it;
    if (!modes->values.allFinite() || !V.allFinite()) return false;
    const double width = std::abs(modes->values(kModes - 1) - sigma);
    const double v0 = modes->values(0), v1 = modes->values(1);
    if (it >= 2 && std::abs(v0 - previous0) <= kRitzTolerance * width &&
        std::abs(v1 - previous1) <= kRitzTolerance * width) {
      // Rayleigh–Ritz again on the converged subspace with the term-by-term form: the factor's
      // round-off perturbs the subspace by ~eps |H| / gap, which moves the Ritz values only by
      // its square, while the factor's own values carry ~eps |H| (QuadraticForms).
      // V is M-orthonormal up to the cancellation in Y Z; made so again first.
      Eigen::MatrixXd Mv = V.transpose() * metric.asDiagonal() * V;
      Mv = 0.5 * (Mv + Mv.transpose()).eval();
      const Eigen::LLT<Eigen::MatrixXd> llt(Mv);
      if (llt.info() != Eigen::Success) return false;
      V = llt.matrixU().solve<Eigen::OnTheRight>(V);
      const Eigen::MatrixXd Q = QuadraticForms(model, state, V);
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> refined(Q);
      if (refined.info() != Eigen::Success) return false;
      modes->values = refined.eigenvalues();
      modes->vectors = V * refined.eigenvectors();
      return modes->values.allFinite() && modes->vectors.allFinite();
    }
    previous0 = v0, previous1 = v1;
  }
  modes->vectors = V;
  return false;
}

}  // namespace

// Derivatives of the gradient g (free dofs, held rows zero) with respect to a turn phi of a
// clamp's frame about world axes, at the clamp's point: clamp A's (vertex 0's stencil, its
// ghost edge behind x_0) or the end clamp's (vertex n's, its ghost after x_n). The frame turned
// by phi moves the ghost's far vertex by phi x (l t) and turns its d1 about t by phi . t, which
// in the stencil is the ghost's twist angle; its perpendicular part follows from the transport
// of the ghost's reference director to the turned tangent (to first order, all a Jet carries).
// *dg_dphi: num_free_dofs x 3; *torque (optional): dPi/d(phi . t), the torque holding the frame
// about its tangent [N m]. Declared in sensitivity.h: the fit's fitted clamp angles need it too.
void ClampTurnGradients(const RodModel& model, const RodState& s, bool end,
                        Eigen::MatrixXd* dg_dphi, double* torque) {
  using J = ceres::Jet<double, 3>;
  const int n = model.num_edges();
  const int vertex = end ? n : 0;
  double q[11];
  VertexStencilConstants c;
  std::array<int, 11> dof;
  GatherVertexStencil(model, s, vertex, q, &c, &dof);
  J qj[11];
  for (int k = 0; k < 11; ++k) qj[k] = J(q[k]);
  const Vec3 t = end ? s.end_t : s.clamp_t;
  const double l = end ? model.end_ghost_length() : model.rest_edge_length(0);
  // d(far vertex) / dphi: behind the clamp x_0 - l R t, after the end x_n + l R t.
  const Mat3 D = end ? Mat3(-l * Hat(t)) : Mat3(l * Hat(t));
  const int vertex_slot = end ? 6 : 0, twist_slot = end ? 10 : 9;
  for (int r = 0; r < 3; ++r)
    for (int a = 0; a < 3; ++a) {
      qj[vertex_slot + r].v[a] = D(r, a);
      qj[twist_slot].v[a] = t[a];
    }
  J gj[11];
  VertexGradient<J>(c, qj, gj);
  dg_dphi->setZero(model.num_free_dofs(), 3);
  const std::vector<char>& held = HeldDofs(model);
  for (int k = 0; k < 11; ++k)
    if (dof[k] >= 0 && !held[dof[k]]) dg_dphi->row(dof[k]) += gj[k].v.transpose();
  if (torque) *torque = gj[twist_slot].a;
}

namespace {

// dg/droll and the clamp's torque dPi/droll.
VecX RollGradientDerivative(const RodModel& model, const RodState& s, double* torque) {
  Eigen::MatrixXd d;
  ClampTurnGradients(model, s, /*end=*/false, &d, torque);
  return d * s.clamp_t;
}

// The continuation metric W: |dz|^2 = dq^T M dq / L^3 + droll^2 (dimensionless, in rad^2).
VecX ContinuationMetric(const VecX& metric, double L) {
  VecX w(metric.size() + 1);
  w.head(metric.size()) = metric / (L * L * L);
  w[metric.size()] = 1.0;
  return w;
}

// The bordered system [[H (+ shift), b], [c_q^T, c_r]] of the pseudo-arclength corrector and of
// the curve's tangent: bordering with the banded LU of H (indefinite beyond the crossing) and one
// step of iterative refinement on the whole system (near a crossing H is nearly singular, and
// bordering alone loses digits to cancellation along its null vector; the bordered matrix itself
// is regular through a fold).
class BorderedSolver : public LinearSolver {
 public:
  void Set(const BandedSymmetric* H, const VecX* b, const VecX* c) { H_ = H, b_ = b, c_ = c; }
  bool Factor(double shift) override {
    shift_ = shift;
    band_.SetFromSymmetric(*H_);
    if (shift != 0.0)
      for (int i = 0; i < band_.size(); ++i) band_.At(i, i) += shift;
    if (!lu_.Factor(band_)) return false;
    x1_ = lu_.Solve(*b_);
    const int n = H_->size();
    schur_ = (*c_)[n] - c_->head(n).dot(x1_);
    return std::isfinite(schur_) && schur_ != 0.0 && x1_.allFinite();
  }
  void Solve(VecX* x) const override {
    const VecX rhs = *x;
    VecX sol = Raw(rhs);
    sol += Raw(rhs - Apply(sol));
    *x = sol;
  }
  double MaxDiagonal() const override {
    const double d = H_->band().row(0).cwiseAbs().maxCoeff();
    return std::isfinite(d) ? d : std::numeric_limits<double>::quiet_NaN();
  }

 private:
  VecX Raw(const VecX& rhs) const {
    const int n = H_->size();
    VecX out(n + 1);
    out.head(n) = lu_.Solve(rhs.head(n));
    const double y = (rhs[n] - c_->head(n).dot(out.head(n))) / schur_;
    out.head(n) -= y * x1_;
    out[n] = y;
    return out;
  }
  VecX Apply(const VecX& z) const {
    const int n = H_->size();
    VecX out(n + 1);
    out.head(n) = H_->Multiply(z.head(n)) + shift_ * z.head(n) + z[n] * *b_;
    out[n] = c_->dot(z);
    return out;
  }
  const BandedSymmetric* H_ = nullptr;
  const VecX *b_ = nullptr, *c_ = nullptr;
  double shift_ = 0.0, schur_ = 0.0;
  BandedMatrix band_;
  BandedLU lu_;
  VecX x1_;
};

// The pseudo-arclength corrector as a Newton problem (newton_minimizer.h): unknowns [free dofs,
// roll], residual [g(q, roll); c . S - ds], S the displacement from the base in the increments'
// chart (the predictor's plus every accepted step's) and c = W t the base's unit tangent in the
// continuation metric. It has no potential (the roll is an unknown): the merit is the residual.
class ArclengthProblem : public RodNewtonProblem {
 public:
  ArclengthProblem(const RodModel& model, const Vec3& t0, const Vec3& d1_0, const VecX& cmetric)
      : RodNewtonProblem(model, kCorrectorStep, model.length()),
        t0_(t0),
        d1_0_(d1_0),
        cmetric_(cmetric),
        n_(model.num_free_dofs()) {
    w_.resize(n_ + 1);
    w_.head(n_) = weights_;
    w_[n_] = model.force_scale();  // an arclength error of 1 rad weighs like the load scale
  }

  /// The predictor base + ds t; false when the retraction fails (an edge would fold back).
  bool Start(const RodState& base, double base_roll, const VecX& tangent, double ds) {
    c_ = cmetric_.cwiseProduct(tangent);
    ds_ = ds;
    const VecX head = tangent.head(n_);
    if (!ApplyStep(model_, base, head, ds, &current())) return false;
    roll_ = base_roll + ds * tangent[n_];
    if (!SetClampFrame(model_, t0_, RolledD1(t0_, d1_0_, roll_), &current())) return false;
    S_ = ds * tangent;
    CurrentChanged();
    return true;
  }
  double roll() const { return roll_; }
  const VecX& displacement() const { return S_; }

  int NumDofs() const override { return n_ + 1; }
  void Evaluate(bool matrix, VecX* r) override {
    const RodFrames& frames = CurrentFrames();
    if (matrix) {
      AssembleHessian(model_, current(), EnergyTerms(), &g_, &H_, &frames);
      b_ = RollGradientDerivative(model_, current(), nullptr);
      solver_.Set(&H_, &b_, &c_);
    } else {
      AssembleGradient(model_, current(), EnergyTerms(), &g_, &frames);
    }
    r->resize(n_ + 1);
    r->head(n_) = g_;
    (*r)[n_] = c_.dot(S_) - ds_;
  }
  double Energy() override { return 0.0; }
  bool Retract(const VecX& step, double alpha) override {
    head_ = step.head(n_);
    if (!RodNewtonProblem::Retract(head_, alpha)) return false;
    roll_trial_ = roll_ + alpha * step[n_];
    S_trial_ = S_ + alpha * step;
    return SetClampFrame(model_, t0_, RolledD1(t0_, d1_0_, roll_trial_), &trial());
  }
  double TrialEnergy() override { return 0.0; }
  void TrialResidual(VecX* r) override {
    AssembleGradient(model_, trial(), EnergyTerms(), &g_, &TrialFrames());
    r->resize(n_ + 1);
    r->head(n_) = g_;
    (*r)[n_] = c_.dot(S_trial_) - ds_;
  }
  void AcceptTrial() override {
    RodNewtonProblem::AcceptTrial();
    std::swap(roll_prev_, roll_);
    std::swap(roll_, roll_trial_);
    std::swap(S_prev_, S_);
    std::swap(S_, S_trial_);
  }
  void RestorePrevious() override {
    RodNewtonProblem::RestorePrevious();
    std::swap(roll_prev_, roll_);
    std::swap(S_prev_, S_);
  }
  StepCaps Caps(const VecX& step) override {
    head_ = step.head(n_);
    StepCaps caps = RodNewtonProblem::Caps(head_);
    const double turn = std::abs(step[n_]);
    caps.turn = std::max(caps.turn, turn);
    if (caps.alpha * turn > kMaxTurnPerStep) caps.alpha = kMaxTurnPerStep / turn;
    return caps;
  }
  RelativeStep Measure(const VecX& step) override {
    head_ = step.head(n_);
    RelativeStep s = RodNewtonProblem::Measure(head_);
    s.theta = std::max(s.theta, std::abs(step[n_]) / step_tolerance_);
    return s;
  }
  const VecX& NormWeights() override { return w_; }
  NewtonTolerances Tolerances() override {
    return {kCorrectorTolerance * model_.force_scale(), ResidualFloor(model_, w_)};
  }
  LinearSolver& Solver() override { return solver_; }

 private:
  Vec3 t0_, d1_0_;
  VecX cmetric_;
  int n_;
  VecX w_, c_, S_, S_trial_, S_prev_, g_, b_, head_;
  double ds_ = 0.0, roll_ = 0.0, roll_trial_ = 0.0, roll_prev_ = 0.0;
  BandedSymmetric H_;
  BorderedSolver solver_;
};

// A point of the path with what the search reads there.
struct PathPoint {
  RodState q;
  double roll = 0.0;
  double lambda = 0.0;
  double torque = 0.0;
  Modes modes;
  VecX tangent;  // unit in W, [dq; droll], oriented along the continuation
};

// Everything the search needs of one model.
struct Search {
  const RodModel& model;
  Vec3 t0, d1_0;
  VecX metric, cmetric;
  std::vector<char> held;
  double lambda_unit = 0.0;
  double direction = 1.0;
  CriticalTwistResult* result;
};

// Assembles H at p.q and finds its lowest modes (sigma from `shift` down), dg/droll and the
// torque. *factor_here: whether H itself (sigma = 0) was positive definite.
bool Analyse(const Search& s, PathPoint* p, double shift, BandedSymmetric* H, bool* positive) {
  VecX g;
  AssembleHessian(s.model, p->q, EnergyTerms(), &g, H);
  const bool ok =
      LowestModes(s.model, p->q, *H, s.metric, s.held, shift, s.lambda_unit, &p->modes);
  s.result->eigen_iterations += p->modes.iterations;
  if (!ok) return false;
  p->lambda = p->modes.values(0);
  if (positive) *positive = p->modes.shift == 0.0 && shift == 0.0;
  RollGradientDerivative(s.model, p->q, &p->torque);
  return true;
}

// The unit tangent at a stable point from dq/droll = -H^-1 dg/droll (H positive definite).
bool NaturalTangent(const Search& s, const PathPoint& p, const BandedSymmetric& H, VecX* t) {
  BandedCholesky chol;
  if (!chol.Factor(H)) return false;
  double torque = 0.0;
  const VecX b = RollGradientDerivative(s.model, p.q, &torque);
  const int n = static_cast<int>(b.size());
  t->resize(n + 1);
  t->head(n) = -chol.Solve(b);
  (*t)[n] = 1.0;
  *t *= s.direction / std::sqrt(t->dot(s.cmetric.cwiseProduct(*t)));
  return t->allFinite();
}

// The unit tangent at p (H its Hessian) oriented by `previous`: the null vector of [H, g_r]
// with the row previous^T W = 1.
bool CurveTangent(const Search& s, const PathPoint& p, const BandedSymmetric& H,
                  const VecX& previous, VecX* t) {
  const VecX b = RollGradientDerivative(s.model, p.q, nullptr);
  const VecX c = s.cmetric.cwiseProduct(previous);
  BorderedSolver solver;
  solver.Set(&H, &b, &c);
  if (!solver.Factor(0.0) && !solver.Factor(1e-12 * solver.MaxDiagonal())) return false;
  const int n = static_cast<int>(b.size());
  *t = VecX::Zero(n + 1);
  (*t)[n] = 1.0;
  solver.Solve(t);
  *t /= std::sqrt(t->dot(s.cmetric.cwiseProduct(*t)));
  return t->allFinite();
}

// The corrector from `base` by arclength ds along base.tangent: the equilibrium on the
// hyperplane base.tangent . W (z - z_base) = ds, on the one minimizer.
bool Correct(const Search& s, const PathPoint& base, double ds, PathPoint* out) {
  ArclengthProblem problem(s.model, s.t0, s.d1_0, s.cmetric);
  if (!problem.Start(base.q, base.roll, base.tangent, ds)) return false;
  NewtonOptions o;
  o.merit = Merit::kResidual;
  o.max_iterations = kCorrectorIterations;
  NewtonMinimizer minimizer(o);
  const NewtonSummary r = minimizer.Minimize(&problem);
  ++s.result->corrector_solves;
  s.result->newton_iterations += r.iterations;
  if (!r.converged()) return false;
  // Farther from the predictor than a fraction of the step: the chord went elsewhere.
  const VecX off = problem.displacement() - ds * base.tangent;
  if (std::sqrt(off.dot(s.cmetric.cwiseProduct(off))) > kCorrectorJump * std::abs(ds)) return false;
  out->q = problem.current();
  out->roll = problem.roll();
  out->modes = base.modes;  // warm start
  return true;
}

void Record(const Search& s, const PathPoint& p, bool arclength) {
  CriticalTwistPathPoint pp;
  pp.roll_rad = p.roll;
  pp.lambda_min = p.lambda;
  pp.clamp_torque_Nm = p.torque;
  pp.arclength = arclength;
  s.result->path.push_back(pp);
}

// How far below the lowest eigenvalue the shift of the inverse iteration goes: a tenth of the
// subspace's spread, so that H - sigma M stays well away from singular (a shift at round-off
// distance makes every column of the iteration the same null vector) while the convergence rate,
// (lambda_1 - sigma) / (lambda_7 - sigma), stays below a tenth.
double ShiftMargin(const Modes& m) {
  return 0.1 * (m.values(m.values.size() - 1) - m.values(0));
}

int Multiplicity(const Modes& m, double unit) {
  int k = 1;
  while (k < m.values.size() && m.values(k) - m.values(0) <= kMultipleEigenvalue * unit) ++k;
  return k;
}

void Finish(const Search& s, const PathPoint& p, CriticalTwistResult* res) {
  res->critical_roll_rad = p.roll;
  res->lambda_min = p.lambda;
  res->multiplicity = Multiplicity(p.modes, s.lambda_unit);
  res->clamp_torque_Nm = p.torque;
  res->state = p.q;
  res->mode = p.modes.vectors.col(0);
}

// The continuation's state between its phases: the last accepted point, the step and what it
// predicts of the crossing, the steps spent.
struct Walk {
  PathPoint a;                 // the last accepted point
  BandedSymmetric H;           // the Hessian at the last analysed point
  double step = 0.0;           // the next natural step [rad]
  // The roll [rad] to the crossing predicted at a (infinite: none predicted).
  double predicted = std::numeric_limits<double>::infinity();
  bool by_failure = false;     // the natural steps ended shrinking, not by a prediction
  int steps = 0;               // steps tried, natural and arclength (options.max_steps)
};

// The crossing bracketed on the arclength from base (lambda > 0) by ds to b (lambda <= 0).
struct Bracket {
  PathPoint base, b;
  double ds = 0.0;
};

// The phases below return whether the search goes on to the next phase; when not, res holds its
// end (ok with its finding, or a failure and why).
bool Failed(CriticalTwistResult* res, const std::string& why) {
  res->ok = false;
  res->message = why;
  return false;
}

// Why the critical twist cannot be sought on this model from this state ("" when it can).
std::string Unsupported(const RodModel& model, const RodState& untwisted,
                        const CriticalTwistOptions& options) {
  std::string why;
  if (!options.Check(&why)) return "invalid options: " + why;
  if (!model.has_end_clamp() || !model.end_twist_held())
    return "the critical twist needs an end clamp that holds the frame (end_clamp with a "
           "normal): without it the roll twists nothing";
  if (model.nonconservative()) return "the critical twist needs a case without moments";
  if (model.symmetric()) return "the critical twist needs the whole rod (no symmetry plane)";
  if (untwisted.num_edges() != model.num_edges() || untwisted.x.cols() != model.num_vertices())
    return "the untwisted state does not match the model's segment count";
  const Vec3 t0 = model.clamp_tangent(), d1_0 = model.clamp_d1();
  if ((untwisted.clamp_t - t0).norm() > 1e-9 || (untwisted.clamp_d1 - d1_0).norm() > 1e-9)
    return "the untwisted state's clamp frame is not the model's";
  return "";
}

// The path's first point: the untwisted equilibrium, re-solved on the model (a warm start: an
// iteration or two), strictly stable, with its tangent.
bool StartPath(const Search& s, const RodState& untwisted, const StaticsOptions& statics,
               StaticsWorkspace* workspace, Walk* w) {
  CriticalTwistResult& res = *s.result;
  PathPoint& a = w->a;
  a.q = untwisted;
  if (!SetClampFrame(s.model, s.t0, s.d1_0, &a.q))
    return Failed(&res, "the untwisted state has folded edges");
  const StaticsSummary first = SolveStatics(s.model, statics, &a.q, workspace);
  res.newton_iterations += first.iterations;
  if (!first.converged)
    return Failed(&res, "the untwisted equilibrium did not solve: " + first.reason);
  bool positive = false;
  if (!Analyse(s, &a, 0.0, &w->H, &positive))
    return Failed(&res, "the eigenvalues of the untwisted equilibrium did not converge");
  if (!positive || !(a.lambda > kStrictlyStable * s.lambda_unit)) {
    char buf[200];
    std::snprintf(buf, sizeof(buf),
                  "the untwisted equilibrium is not strictly stable (lambda_min %.3e, %.1e of "
                  "lambda_unit): no branch to follow",
                  a.lambda, a.lambda / s.lambda_unit);
    Finish(s, a, &res);
    return Failed(&res, buf);
  }
  if (!NaturalTangent(s, a, w->H, &a.tangent))
    return Failed(&res, "no tangent at the untwisted equilibrium");
  Record(s, a, false);
  return true;
}

// 1. Natural steps in the roll: each point solved on the rolled model from the tangent's
// predictor, until the crossing is predicted near (or the steps shrink below the smallest).
bool NaturalSteps(const Search& s, const CriticalTwistOptions& options,
                  const StaticsOptions& statics, StaticsWorkspace* workspace, Walk* w) {
  CriticalTwistResult& res = *s.result;
  const RodModel& model = s.model;
  const double range = std::abs(options.max_roll_rad);
  const double L = model.length();
  PathPoint& a = w->a;
  w->step = options.initial_step_rad;
  double predicted_linear = std::numeric_limits<double>::infinity();
  double before_roll = 0.0, before_lambda = 0.0;  // the accepted point before a
  bool have_before = false;
  const int n = model.num_free_dofs();
  for (;;) {
    if (s.direction * a.roll >= range * (1.0 - 1e-15)) {
      res.ok = true;
      res.kind = TwistInstability::kNoneInRange;
      Finish(s, a, &res);
      char buf[160];
      std::snprintf(buf, sizeof(buf), "stable up to roll %.6g rad (lambda_min %.3e)", a.roll,
                    a.lambda);
      res.message = buf;
      return false;
    }
    if (++w->steps > options.max_steps)
      return Failed(&res, "step cap reached at roll " + std::to_string(a.roll) + " rad");
    const double h = std::min(w->step, range - s.direction * a.roll);
    const double roll = a.roll + s.direction * h;
    bool ok = true;
    PathPoint c;
    RodState predictor;
    // Predictor: along the tangent by dr (its W-length is h / |t_r|).
    ok = ApplyStep(model, a.q, VecX(a.tangent.head(n)), h / std::abs(a.tangent[n]), &predictor);
    std::unique_ptr<RodModel> rolled_model;
    try {
      rolled_model = std::make_unique<RodModel>(RolledModel(model, RolledD1(s.t0, s.d1_0, roll)));
    } catch (const std::exception& e) {  // the same rod as `model`'s: not expected
      return Failed(&res, std::string("the rolled case is not a valid rod: ") + e.what());
    }
    const RodModel& rolled = *rolled_model;
    ok = ok && SetClampFrame(model, rolled.clamp_tangent(), rolled.clamp_d1(), &predictor);
    if (ok) {
      c.q = predictor;
      const StaticsSummary r = SolveStatics(rolled, statics, &c.q, workspace);
      res.newton_iterations += r.iterations;
      ok = r.converged && r.stable;
    }
    if (ok) {
      // A jump to another branch: the solution far from the predictor.
      double moved = 0.0, corrected = 0.0;
      for (int i = 0; i < a.q.x.cols(); ++i) {
        moved = std::max(moved, (predictor.x.col(i) - a.q.x.col(i)).norm());
        corrected = std::max(corrected, (c.q.x.col(i) - predictor.x.col(i)).norm());
      }
      ok = corrected <= std::max(kJumpFraction * moved, kJumpFloor * L);
    }
    if (ok) {
      c.roll = roll;
      c.modes = a.modes;
      bool positive = false;
      ok = Analyse(s, &c, 0.0, &w->H, &positive) && positive &&
           NaturalTangent(s, c, w->H, &c.tangent);
    }
    if (!ok) {
      ++res.failed_steps;
      w->step = 0.5 * h;
      if (w->step < options.min_step_rad) {  // the crossing is within reach: arclength
        w->by_failure = true;
        return true;
      }
      continue;
    }
    ++res.natural_steps;
    Record(s, c, false);
    // The crossing ahead, from lambda here and at a, extrapolated linearly in the roll (a
    // bifurcation's distance; a fold's, where lambda ~ sqrt(r_f - r), overestimated twice) and as
    // lambda^2 (a fold's distance; a bifurcation's underestimated). The model that predicted
    // lambda here better from the two points before bounds the next step (the lambda^2 model,
    // which is safe, until there are three points); the linear one says when to hand over.
    double& predicted = w->predicted;
    predicted = std::numeric_limits<double>::infinity();
    predicted_linear = std::numeric_limits<double>::infinity();
    if (c.lambda < a.lambda) {
      predicted_linear = c.lambda * h / (a.lambda - c.lambda);
      predicted = c.lambda * c.lambda * h / (a.lambda * a.lambda - c.lambda * c.lambda);
      if (have_before) {
        const double r = h / std::abs(a.roll - before_roll);
        const double linear = a.lambda + (a.lambda - before_lambda) * r;
        const double square =
            std::sqrt(std::max(0.0, a.lambda * a.lambda + (a.lambda * a.lambda -
                                                           before_lambda * before_lambda) * r));
        if (std::abs(linear - c.lambda) < std::abs(square - c.lambda)) predicted = predicted_linear;
      }
    }
    before_roll = a.roll, before_lambda = a.lambda, have_before = true;
    a = std::move(c);
    w->step = std::min({options.max_step_rad, 1.5 * h, kCrossingFraction * predicted});
    if (predicted_linear < kArclengthTakeover || w->step < options.min_step_rad) return true;
  }
}

// 2. Pseudo-arclength steps through the crossing, until lambda is at or below zero. The first
// step: half again the predicted distance, or twice the last step tried, along the arclength
// (|droll| = |t_r| ds).
bool ArclengthSteps(const Search& s, const CriticalTwistOptions& options, Walk* w,
                    Bracket* bracket) {
  CriticalTwistResult& res = *s.result;
  const double range = std::abs(options.max_roll_rad);
  const int n = s.model.num_free_dofs();
  const double roll_share = std::max(std::abs(w->a.tangent[n]), 1e-3);
  double& ds = bracket->ds;
  ds = !w->by_failure && std::isfinite(w->predicted) ? 1.5 * w->predicted : 2.0 * w->step;
  ds = std::min(options.max_step_rad, ds / roll_share);
  PathPoint& base = bracket->base;
  base = w->a;
  for (;;) {
    if (++w->steps > options.max_steps)
      return Failed(&res, "step cap reached at roll " + std::to_string(base.roll) + " rad");
    PathPoint c;
    bool ok = Correct(s, base, ds, &c);
    if (ok) {
      const double guess = std::min(0.0, base.lambda) - ShiftMargin(base.modes);
      ok = Analyse(s, &c, guess, &w->H, nullptr) &&
           CurveTangent(s, c, w->H, base.tangent, &c.tangent);
    }
    if (!ok) {
      ds *= 0.5;
      if (ds < kMinArclengthStep)
        return Failed(&res, "the arclength continuation stalled at roll " +
                                std::to_string(base.roll) + " rad");
      continue;
    }
    ++res.arclength_steps;
    Record(s, c, true);
    if (c.lambda <= 0.0) {
      bracket->b = std::move(c);
      return true;
    }
    if (s.direction * c.roll > range) {
      res.ok = true;
      res.kind = TwistInstability::kNoneInRange;
      Finish(s, c, &res);
      res.message = "stable up to roll " + std::to_string(c.roll) + " rad";
      return false;
    }
    const double slope = (c.lambda - base.lambda) / ds;
    const double ahead = slope < 0.0 ? 1.5 * c.lambda / -slope : 2.0 * ds;
    ds = std::min({options.max_step_rad, 2.0 * ds, ahead});
    base = std::move(c);
  }
}

// 3. Locate the crossing on the arclength from the base (lambda > 0) to b (lambda <= 0):
// secant steps through the last two evaluations (lambda is smooth in the arclength, crossing
// zero linearly at a fold and at a bifurcation alike), kept inside the bracket (bisection when
// one leaves it), until a step is below the tolerance. Ends the search.
void Locate(const Search& s, const CriticalTwistOptions& options, const Bracket& bracket,
            BandedSymmetric* H) {
  CriticalTwistResult& res = *s.result;
  const double range = std::abs(options.max_roll_rad);
  const int n = s.model.num_free_dofs();
  const PathPoint& base = bracket.base;
  const PathPoint& b = bracket.b;
  const bool fold = base.tangent[n] * b.tangent[n] < 0.0;
  double s_lo = 0.0, f_lo = base.lambda, s_hi = bracket.ds, f_hi = b.lambda;
  double s_a = s_lo, f_a = f_lo, s_b = s_hi, f_b = f_hi, roll_b = b.roll;
  double last_step = s_hi - s_lo, last_roll_step = std::abs(b.roll - base.roll);
  PathPoint best = b;
  while (last_step > options.locate_tolerance_rad && f_b != 0.0) {
    if (res.locate_iterations >= options.max_locate_iterations) {
      Failed(&res, "the crossing was not located within " +
                       std::to_string(options.max_locate_iterations) + " iterations (last step " +
                       std::to_string(last_step) + " rad of arclength)");
      return;
    }
    ++res.locate_iterations;
    double sm = (s_a * f_b - s_b * f_a) / (f_b - f_a);
    if (!(sm > s_lo && sm < s_hi)) sm = 0.5 * (s_lo + s_hi);
    PathPoint c;
    const double guess = std::min(0.0, std::min(f_lo, f_hi)) - ShiftMargin(base.modes);
    if (!Correct(s, base, sm, &c) || !Analyse(s, &c, guess, H, nullptr)) {
      Failed(&res, "the corrector failed while locating the crossing near roll " +
                       std::to_string(base.roll) + " rad");
      return;
    }
    const double fc = c.lambda;
    (fc > 0.0 ? s_lo : s_hi) = sm;
    (fc > 0.0 ? f_lo : f_hi) = fc;
    last_step = std::min(std::abs(sm - s_b), s_hi - s_lo);
    last_roll_step = std::abs(c.roll - roll_b);
    s_a = s_b, f_a = f_b;
    s_b = sm, f_b = fc, roll_b = c.roll;
    if (std::abs(fc) <= std::abs(best.lambda)) best = std::move(c);
  }
  res.bracket_rad = last_roll_step;
  Finish(s, best, &res);
  res.kind = fold ? TwistInstability::kFold : TwistInstability::kBifurcation;
  res.ok = true;
  char buf[200];
  if (s.direction * best.roll > range) {
    res.kind = TwistInstability::kNoneInRange;
    std::snprintf(buf, sizeof(buf), "first loss of stability at roll %.10g rad, beyond the range",
                  best.roll);
  } else {
    std::snprintf(buf, sizeof(buf), "%s at roll %.10g rad (%.4f deg)",
                  TwistInstabilityName(res.kind), best.roll, best.roll * 180.0 / M_PI);
  }
  res.message = buf;
}

}  // namespace

// The phases (start, natural steps, arclength steps, location) run in this order, each from the
// last accepted point and step the one before left in the walk.
CriticalTwistResult CriticalTwist(const RodModel& model, const RodState& untwisted,
                                  const CriticalTwistOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  CriticalTwistResult res;
  auto done = [&]() {
    res.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    return res;
  };
  if (const std::string why = Unsupported(model, untwisted, options); !why.empty()) {
    Failed(&res, why);
    return done();
  }
  const Vec3 t0 = model.clamp_tangent(), d1_0 = model.clamp_d1();
  Search s{model, t0, d1_0, LengthMetric(model), VecX(), HeldDofs(model), LambdaUnit(model),
           options.max_roll_rad > 0 ? 1.0 : -1.0, &res};
  s.cmetric = ContinuationMetric(s.metric, model.length());
  res.lambda_unit = s.lambda_unit;
  StaticsOptions statics = options.statics;
  statics.escape_saddles = false;
  statics.max_load_steps = 1;
  std::shared_ptr<StaticsWorkspace> workspace = NewStaticsWorkspace();

  Walk w;
  Bracket bracket;
  if (StartPath(s, untwisted, statics, workspace.get(), &w) &&
      NaturalSteps(s, options, statics, workspace.get(), &w) &&
      ArclengthSteps(s, options, &w, &bracket))
    Locate(s, options, bracket, &w.H);
  return done();
}

// ---------------------------------------------------------------------------------------------
// Derivatives.

namespace {

bool ParameterTerms(const CriticalTwistParameter& p, EnergyTerms* unit);

// The parameter's dg/dp (free dofs, held rows zero) at s: a stiffness's or a spring zone's unit
// gradient, the weights' part of the loads, or a clamp frame's turn about the axis.
VecX ParameterGradient(const RodModel& model, const RodState& s, const CriticalTwistParameter& p) {
  using Kind = CriticalTwistParameter::Kind;
  VecX g;
  switch (p.kind) {
    case Kind::kStiffness:
    case Kind::kSpring: {
      EnergyTerms unit;
      ParameterTerms(p, &unit);
      AssembleGradient(model, s, unit, &g);
      return g;
    }
    case Kind::kLinearDensity: {
      // Pi's weights: -sum_i w_i . x_i, linear in the density.
      g = VecX::Zero(model.num_free_dofs());
      for (int i = 1; i <= model.num_edges(); ++i)
        if (model.held_at_vertex(i) < 0)
          g.segment<3>(RodModel::VertexDof(i)) = -model.vertex_weight(i);
      return g;
    }
    case Kind::kClampRotation:
    case Kind::kEndClampRotation: {
      Eigen::MatrixXd d;
      ClampTurnGradients(model, s, p.kind == Kind::kEndClampRotation, &d);
      return d * p.axis;
    }
  }
  return g;
}

// The terms a stiffness or spring parameter scales (U is linear in each, so their Hessian is
// the parameter's own dH/dlog p); false for the density (dead loads) and the clamps (they move
// the state only).
bool ParameterTerms(const CriticalTwistParameter& p, EnergyTerms* unit) {
  using Kind = CriticalTwistParameter::Kind;
  if (p.kind == Kind::kStiffness) {
    *unit = EnergyTerms::Only(-1);
    unit->bend1 = p.bend1, unit->bend2 = p.bend2, unit->twist = p.twist, unit->stretch = p.stretch;
    return true;
  }
  if (p.kind == Kind::kSpring) {
    *unit = EnergyTerms::OnlySprings(&p.spring);
    return true;
  }
  return false;
}

// V^T H V with H assembled at s moved by h along the direction: the free dofs by h dq (the
// solver's retraction), clamp A's frame turned by h (droll t + phi_a) at x_0, the end clamp's by
// h phi_b at x_n.
bool QuadraticAlong(const RodModel& model, const RodState& s, const VecX& dq, double droll,
                    const Vec3& phi_a, const Vec3& phi_b, double h, const Eigen::MatrixXd& V,
                    Eigen::MatrixXd* Q) {
  RodState m;
  if (!ApplyStep(model, s, dq, h, &m)) return false;
  const Mat3 Ra = RotationOf(h * (droll * s.clamp_t + phi_a));
  const Mat3 Rb = RotationOf(h * phi_b);
  m.clamp_t = Ra * s.clamp_t;
  m.clamp_d1 = Ra * s.clamp_d1;
  m.end_t = Rb * s.end_t;
  m.end_u = Rb * s.end_u;
  if (!UpdateReferenceFrames(model, m, &m)) return false;
  *Q = QuadraticForms(model, m, V);
  return true;
}

// d(V^T H V)/dh at h = 0 along the direction, by fourth-order central differences with the
// largest tangent turn or twist change kDifferenceTurn.
bool QuadraticDerivative(const RodModel& model, const RodState& s, const VecX& dq, double droll,
                         const Vec3& phi_a, const Vec3& phi_b, const Eigen::MatrixXd& V,
                         Eigen::MatrixXd* D) {
  double twist = 0.0;
  for (int j = 0; j < model.num_edges(); ++j) twist = std::max(twist, std::abs(dq[RodModel::TwistDof(j)]));
  const double turn = std::max({MaxTangentTurn(model, s, dq), twist, std::abs(droll),
                                phi_a.norm(), phi_b.norm()});
  if (!(turn > 0.0)) {  // nothing moves: no change
    *D = Eigen::MatrixXd::Zero(V.cols(), V.cols());
    return true;
  }
  const double h = kDifferenceTurn / turn;
  Eigen::MatrixXd q1, q2, m1, m2;
  if (!QuadraticAlong(model, s, dq, droll, phi_a, phi_b, h, V, &q1) ||
      !QuadraticAlong(model, s, dq, droll, phi_a, phi_b, -h, V, &m1) ||
      !QuadraticAlong(model, s, dq, droll, phi_a, phi_b, 2 * h, V, &q2) ||
      !QuadraticAlong(model, s, dq, droll, phi_a, phi_b, -2 * h, V, &m2))
    return false;
  *D = (8.0 * (q1 - m1) - (q2 - m2)) / (12.0 * h);
  *D = 0.5 * (*D + D->transpose()).eval();
  return true;
}

}  // namespace

bool CriticalTwistDerivatives(const RodModel& model, const CriticalTwistResult& result,
                              const std::vector<CriticalTwistParameter>& parameters,
                              Eigen::VectorXd* d_roll, std::string* why) {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!result.ok || result.kind == TwistInstability::kNoneInRange)
    return fail("no located crossing to differentiate");
  const RodState& s = result.state;
  if (s.num_edges() != model.num_edges()) return fail("the result is not of this model");
  const int n = model.num_free_dofs();
  const std::vector<char>& held = HeldDofs(model);
  const VecX metric = LengthMetric(model);
  const double unit = LambdaUnit(model);
  // The critical eigenvector(s) at the located state.
  BandedSymmetric H;
  VecX g;
  AssembleHessian(model, s, EnergyTerms(), &g, &H);
  Modes modes;
  if (!LowestModes(model, s, H, metric, held, -1e-2 * unit, unit, &modes))
    return fail("the critical eigenvector did not converge");
  const int k = Multiplicity(modes, unit);
  const Eigen::MatrixXd V = modes.vectors.leftCols(k);
  const VecX g_roll = RollGradientDerivative(model, s, nullptr);
  d_roll->resize(static_cast<int>(parameters.size()));
  using Kind = CriticalTwistParameter::Kind;

  if (result.kind == TwistInstability::kFold) {
    const VecX v = V.col(0);
    const double den = v.dot(g_roll);
    if (!(std::abs(den) > 0.0)) return fail("v . dg/droll vanishes: not a fold");
    for (size_t i = 0; i < parameters.size(); ++i)
      (*d_roll)[i] = -v.dot(ParameterGradient(model, s, parameters[i])) / den;
    return d_roll->allFinite() ? true : fail("non-finite derivative");
  }

  // A bifurcation: dlambda/dt along the path for the roll and each parameter. dq/dt = -H^+ g_t:
  // the critical components removed before and after the solve (H is singular there).
  BandedMatrix band;
  band.SetFromSymmetric(H);
  BandedLU lu;
  if (!lu.Factor(band)) return fail("the Hessian at the bifurcation did not factor");
  auto path_tangent = [&](const VecX& g_t) {
    VecX r = -g_t;
    r -= metric.asDiagonal() * (V * (V.transpose() * r));
    VecX y = lu.Solve(r);
    y -= V * (V.transpose() * (metric.asDiagonal() * y));
    for (int i = 0; i < n; ++i)
      if (held[i]) y[i] = 0.0;
    return y;
  };
  // The mean of the cluster's eigenvalue derivatives, and whether they agree (a parameter that
  // splits a double eigenvalue moves the first crossing one-sidedly).
  auto eigen_derivative = [&](const Eigen::MatrixXd& D, double* mean, double* spread) {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(D, Eigen::EigenvaluesOnly);
    *mean = es.eigenvalues().mean();
    *spread = es.eigenvalues()(D.rows() - 1) - es.eigenvalues()(0);
  };
  const Vec3 zero = Vec3::Zero();
  Eigen::MatrixXd D;
  if (!QuadraticDerivative(model, s, path_tangent(g_roll), 1.0, zero, zero, V, &D))
    return fail("the Hessian along the path could not be differenced");
  double dl_droll = 0.0, spread = 0.0;
  eigen_derivative(D, &dl_droll, &spread);
  if (!(std::abs(dl_droll) > 0.0)) return fail("the critical eigenvalue does not cross zero");
  for (size_t i = 0; i < parameters.size(); ++i) {
    const CriticalTwistParameter& p = parameters[i];
    const VecX g_p = ParameterGradient(model, s, p);
    // The branch passes the bifurcation because of a symmetry its loads keep (v . g_roll = 0); a
    // parameter whose load pushes the critical mode (v . g_p != 0, a clamp turned off the axis)
    // makes the bifurcation imperfect, and the critical roll has no derivative there.
    const double overlap = (V.transpose() * g_p).norm() / (g_p.norm() * V.norm() + 1e-300);
    if (overlap > kSymmetryBroken)
      return fail("parameter " + std::to_string(i) +
                  " breaks the symmetry that makes the bifurcation (its load pushes the critical "
                  "mode): the critical roll has no derivative there");
    const VecX dq = path_tangent(g_p);
    const Vec3 phi_a = p.kind == Kind::kClampRotation ? Vec3(p.axis) : zero;
    const Vec3 phi_b = p.kind == Kind::kEndClampRotation ? Vec3(p.axis) : zero;
    if (!QuadraticDerivative(model, s, dq, 0.0, phi_a, phi_b, V, &D))
      return fail("the Hessian along parameter " + std::to_string(i) + " could not be differenced");
    EnergyTerms unit;
    if (ParameterTerms(p, &unit)) D += QuadraticForms(model, s, V, unit);
    double dl = 0.0;
    eigen_derivative(D, &dl, &spread);
    if (spread > 1e-6 * (std::abs(dl) + std::abs(dl_droll)))
      return fail("parameter " + std::to_string(i) +
                  " splits the double critical eigenvalue: the critical roll has one-sided "
                  "derivatives only");
    (*d_roll)[i] = -dl / dl_droll;
  }
  return d_roll->allFinite() ? true : fail("non-finite derivative");
}

}  // namespace rodfit
