// The cost of one case of a fit (case_cost.h).
#include "rodfit/fit/case_cost.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>
#include <thread>

#include "rodfit/model/material_parameters.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/poke.h"
#include "rodfit/solve/reactions.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/sensitivity.h"

namespace rodfit {
namespace fit_internal {
namespace {

void CheckSurfacePoints(const FitInput& in, const std::vector<Fitted>& fitted) {
  bool any = false;
  for (const FitCase& c : in.cases) {
    bool has = false;
    for (const auto& meas : c.measurements) has = has || meas->needs_section();
    if (!has) continue;
    any = true;
    if (!c.load_case.poke)
      throw std::invalid_argument("case " + c.load_case.name + ": surface_points without a poke");
    if (!in.section)
      throw std::invalid_argument("case " + c.load_case.name +
                                  ": surface_points need the cross-section model (section:)");
  }
  for (const Fitted& f : fitted) {
    if (f.ring != 0 && !any)
      throw std::invalid_argument(f.name + ": fitted, but no case has surface_points (the ring's "
                                  "stiffness is seen only through the dented section)");
    if (f.ring == 0 && any)
      throw std::invalid_argument(
          "surface_points constrain the ring's stiffness only: fit rod parameters (here " + f.name +
          ") from other cases without surface_points, then hold them while fitting "
          "ring_bend_stiffness / ring_stretch_stiffness (the section's placement on the rod "
          "moves with them, which the surface residuals' Jacobian does not model)");
  }
}

bool ZonesUse(const FitInput& in, const std::string& parameter) {
  for (const SpringZone& z : in.springs)
    if (z.parameter == parameter) return true;
  return false;
}

}  // namespace


std::vector<Nuisance> Nuisances(const FitInput& in, int first_column) {
  std::vector<Nuisance> out;
  int column = first_column;
  for (size_t c = 0; c < in.cases.size(); ++c) {
    const LoadCase& lc = in.cases[c].load_case;
    auto add = [&](Nuisance::Kind kind, const std::string& held, double sigma, bool end,
                   int pin) {
      Nuisance n;
      n.kind = kind;
      n.case_index = static_cast<int>(c);
      n.held = held;
      n.end_clamp = end;
      n.pin = pin;
      n.sigma = sigma;
      n.first_column = column;
      column += n.size();
      out.push_back(n);
    };
    using K = Nuisance::Kind;
    constexpr double kRad = M_PI / 180.0;
    if (lc.clamp.rotation_prior_deg)
      add(K::kRotation, "clamp", *lc.clamp.rotation_prior_deg * kRad, false, -1);
    if (lc.end_clamp && lc.end_clamp->rotation_prior_deg)
      add(K::kRotation, "end_clamp", *lc.end_clamp->rotation_prior_deg * kRad, true, -1);
    if (lc.clamp.position_prior) add(K::kPosition, "clamp", *lc.clamp.position_prior, false, -1);
    if (lc.end_clamp && lc.end_clamp->position_prior)
      add(K::kPosition, "end_clamp", *lc.end_clamp->position_prior, true, -1);
    if (lc.end_pin && lc.end_pin_position_prior)
      add(K::kPosition, "end_pin", *lc.end_pin_position_prior, false, -1);
    for (size_t k = 0; k < lc.pins.size(); ++k)
      if (lc.pins[k].position_prior)
        add(K::kPosition, "pins[" + std::to_string(k) + "]", *lc.pins[k].position_prior, false,
            static_cast<int>(k));
    if (lc.grasp && lc.grasp->position_prior)
      add(K::kPosition, "grasp", *lc.grasp->position_prior, false, -1);
    if (in.gravity_prior_deg) add(K::kGravity, "gravity", *in.gravity_prior_deg * kRad, false, -1);
  }
  return out;
}

int NuisanceColumns(const std::vector<Nuisance>& nuisances) {
  int columns = 0;
  for (const Nuisance& n : nuisances) columns += n.size();
  return columns;
}

namespace {
Eigen::Matrix3d Cross(const Vec3& v) {
  Eigen::Matrix3d h;
  h << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return h;
}
}  // namespace

// Rodrigues' formula; below theta^2 = 1e-12 its series to second order (the next terms are
// below round-off), so that phi = 0, the prior's mean and every fit's start, is exact.
Eigen::Matrix3d RotationExp(const Vec3& phi) {
  const double theta_sq = phi.squaredNorm();
  const Eigen::Matrix3d K = Cross(phi);
  if (theta_sq < 1e-12) return Eigen::Matrix3d::Identity() + K + 0.5 * K * K;
  const double theta = std::sqrt(theta_sq);
  return Eigen::Matrix3d::Identity() + std::sin(theta) / theta * K +
         (1.0 - std::cos(theta)) / theta_sq * K * K;
}

Eigen::Matrix3d RotationLeftJacobian(const Vec3& phi) {
  const double theta_sq = phi.squaredNorm();
  const Eigen::Matrix3d K = Cross(phi);
  if (theta_sq < 1e-12) return Eigen::Matrix3d::Identity() + 0.5 * K + K * K / 6.0;
  const double theta = std::sqrt(theta_sq);
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / theta_sq * K +
         (theta - std::sin(theta)) / (theta_sq * theta) * K * K;
}

Eigen::Matrix<double, 3, 2> GravityTiltBasis(const Vec3& gravity) {
  const Vec3 g = gravity.normalized();
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (std::abs(g[k]) < std::abs(g[axis])) axis = k;
  const Vec3 b1 = (Vec3::Unit(axis) - g[axis] * g).normalized();
  Eigen::Matrix<double, 3, 2> B;
  B.col(0) = b1;
  B.col(1) = b1.cross(g);
  return B;
}

namespace {
Vec3 Phi(const Nuisance& n, const double* x) {
  return Vec3(x[n.first_column], x[n.first_column + 1], x[n.first_column + 2]);
}
// The gravity nuisance's rotation vector psi = a b1 + b b2.
Vec3 Psi(const Nuisance& n, const Vec3& gravity, const double* x) {
  return GravityTiltBasis(gravity) * Eigen::Vector2d(x[n.first_column], x[n.first_column + 1]);
}
}  // namespace

LoadCase WithNuisances(const LoadCase& load_case, const std::vector<Nuisance>& own,
                       const double* x) {
  LoadCase out = load_case;
  for (const Nuisance& n : own) {
    if (n.kind == Nuisance::Kind::kRotation) {
      const Eigen::Matrix3d R = RotationExp(Phi(n, x));
      if (n.end_clamp) {
        out.end_clamp->tangent = R * load_case.end_clamp->tangent;
        out.end_clamp->normal = R * *load_case.end_clamp->normal;
      } else {
        out.clamp.tangent = R * load_case.clamp.tangent;
        out.clamp.normal = R * load_case.clamp.normal;
      }
    } else if (n.kind == Nuisance::Kind::kPosition) {
      const Vec3 offset = Phi(n, x);
      if (n.held == "clamp") out.clamp.position += offset;
      else if (n.held == "end_clamp") out.end_clamp->position += offset;
      else if (n.held == "end_pin") *out.end_pin += offset;
      else if (n.held == "grasp") out.grasp->position += offset;
      else out.pins[n.pin].position += offset;
    }
  }
  return out;
}

Vec3 GravityWithNuisances(const Vec3& gravity, const std::vector<Nuisance>& own,
                          const double* x) {
  for (const Nuisance& n : own)
    if (n.kind == Nuisance::Kind::kGravity) return RotationExp(Psi(n, gravity, x)) * gravity;
  return gravity;
}

bool NuisancePriorCost::Evaluate(double const* const* parameters, double* residuals,
                                 double** jacobians) const {
  const int cols = parameter_block_sizes()[0];
  const int rows = nuisance_.size();
  for (int i = 0; i < rows; ++i)
    residuals[i] = parameters[0][nuisance_.first_column + i] / nuisance_.sigma;
  if (jacobians && jacobians[0]) {
    std::fill(jacobians[0], jacobians[0] + rows * cols, 0.0);
    for (int i = 0; i < rows; ++i)
      jacobians[0][i * cols + nuisance_.first_column + i] = 1.0 / nuisance_.sigma;
  }
  return true;
}

namespace {

// The free gradient's derivatives by a held point's offset (free dofs x 3, held rows zero), and
// in *moved the first free dof of each held vertex (or ghost vertex) the offset moves with it.
// A held vertex h moved by d changes g by H[:, h] d (H with the held rows and columns kept,
// EnergyTerms::hold off); dead loads have no Hessian. The clamp at s = 0 holds vertex 0 and its
// ghost, which are no dofs: the elastic energy depends on differences of positions only and
// the springs' anchors (the rest shape) move with the clamp, so moving the clamp by d changes g
// as moving every other vertex (held ones and the end ghost's included) by -d does: -H T d.
// Moment loads, which are not in H, are refused with a fitted offset (CaseEvaluator).
void HeldPointOffsetGradients(const RodModel& model, const RodState& state, const Nuisance& n,
                              Eigen::MatrixXd* dg, std::vector<int>* moved) {
  EnergyTerms all;
  all.hold = false;
  VecX g;
  BandedSymmetric H;
  AssembleHessian(model, state, all, &g, &H);
  const int N = model.num_free_dofs(), edges = model.num_edges();
  const int last_vertex = edges + (model.has_end_ghost() ? 1 : 0);  // the end ghost's far one
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(N, 3);
  double sign = 1.0;
  moved->clear();
  if (n.held == "clamp") {
    sign = -1.0;
    for (int i = 1; i <= last_vertex; ++i) T.middleRows<3>(RodModel::VertexDof(i)).setIdentity();
  } else {
    int vertex = -1;
    for (const HeldVertex& h : model.held())
      if (h.Label() == n.held) vertex = h.vertex;
    if (vertex < 1) throw std::logic_error("held point " + n.held + " not in the model");
    moved->push_back(RodModel::VertexDof(vertex));
    if (n.held == "end_clamp") moved->push_back(RodModel::VertexDof(edges + 1));
    for (int d : *moved) T.middleRows<3>(d).setIdentity();
  }
  dg->resize(N, 3);
  for (int k = 0; k < 3; ++k) dg->col(k) = sign * H.Multiply(T.col(k));
  const std::vector<char>& held = HeldDofs(model);
  for (int r = 0; r < N; ++r)
    if (held[r]) dg->row(r).setZero();
}

// The free gradient's derivatives by the gravity nuisance's two angles (free dofs x 2, held rows
// zero): the weight w_i = m_i Exp(psi) g of each free vertex turns about J_l(psi) b_k, and the
// gradient carries -w_i.
void GravityTiltGradients(const RodModel& model, const Eigen::Matrix<double, 3, 2>& axes,
                          Eigen::MatrixXd* dg) {
  dg->setZero(model.num_free_dofs(), 2);
  for (int i = 1; i <= model.num_edges(); ++i) {
    if (model.held_at_vertex(i) >= 0) continue;
    const Vec3 w = model.vertex_weight(i);
    for (int k = 0; k < 2; ++k)
      dg->block<3, 1>(RodModel::VertexDof(i), k) = -Vec3(axes.col(k)).cross(w);
  }
}

}  // namespace

// What `surface_points` need and what they can determine (fit.h).
std::vector<Fitted> FittedParameters(const FitInput& in) {
  std::vector<Fitted> out;
  const bool tied = !in.material.bend_stiffness_2.has_value();
  for (size_t k = 0; k < in.parameters.size(); ++k) {
    const Parameter& p = in.parameters[k];
    if (!p.fit) continue;
    Fitted f;
    f.input_index = static_cast<int>(k);
    f.name = p.name;
    const MaterialParameterInfo* row = FindMaterialParameter(p.name);
    const bool zone_parameter = in.material.spring_parameters.count(p.name) > 0;
    if (!row && !zone_parameter)
      throw std::invalid_argument(p.name + ": not a parameter of the rod model");
    if (row && (row->kind == ParameterKind::kDamping || row->kind == ParameterKind::kMass))
      throw std::invalid_argument(p.name + ": " +
                                  (row->kind == ParameterKind::kMass ? "the rod's mass" : "damping") +
                                  " is seen only in motion, not by a static fit");
    if (row && row->kind == ParameterKind::kRodStiffness) {
      if (row->tied_to && tied)
        throw std::invalid_argument(p.name + ": fitted but tied to " + row->tied_to);
      f.drives = {static_cast<Stiffness>(row->term)};
      // The row a tied one follows drives it too (bend_stiffness moves B2 when isotropic).
      for (const MaterialParameterInfo& other : MaterialParameters())
        if (tied && other.tied_to && p.name == other.tied_to)
          f.drives.push_back(static_cast<Stiffness>(other.term));
    } else if (row && row->kind == ParameterKind::kRing) {
      f.ring = row->term;
    } else {  // spring_stiffness or a zone's own parameter
      f.spring = true;
      f.spring_zone_name = row ? "" : p.name;
      if (in.springs.empty())
        throw std::invalid_argument(p.name +
                                    ": fitted, but the scene has no springs for it to act on");
      if (!ZonesUse(in, f.spring_zone_name))
        throw std::invalid_argument(p.name + ": fitted, but no spring zone uses it");
    }
    out.push_back(f);
  }
  CheckSurfacePoints(in, out);
  return out;
}

Material MaterialAt(const FitInput& in, const std::vector<Fitted>& fitted, const double* logp) {
  Material m = in.material;
  for (size_t k = 0; k < fitted.size(); ++k)
    AssignMaterialParameter(fitted[k].name, std::exp(logp[k]), &m);
  return m;
}

/// Robust loss applied per measurement as an exact residual transform: r~ = phi(s) r with
/// phi = sqrt(rho(s) / s), s = |r|^2, so that 1/2 |r~|^2 = 1/2 rho(s) and Ceres' cost is the
/// robust cost; J~ = phi J + 2 phi'(s) r r^T J.
void ApplyLoss(const ceres::LossFunction* loss, int dim, double* r, double* J, int cols) {
  if (!loss) return;
  double s = 0.0;
  for (int i = 0; i < dim; ++i) s += r[i] * r[i];
  double rho[3];
  loss->Evaluate(s, rho);
  double phi, dphi;
  if (s < 1e-12) {  // rho(s) = s + rho''(0) s^2 / 2 + ...: phi -> 1, phi' -> rho''(0) / 4
    phi = 1.0;
    dphi = rho[2] / 4.0;
  } else {
    phi = std::sqrt(rho[0] / s);
    dphi = (rho[1] * s - rho[0]) / (2.0 * s * s * phi);
  }
  if (J) {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> Jm(
        J, dim, cols);
    const Eigen::Map<const Eigen::VectorXd> rv(r, dim);
    const Eigen::RowVectorXd rtJ = rv.transpose() * Jm;
    Jm = (phi * Jm + 2.0 * dphi * rv * rtJ).eval();
  }
  for (int i = 0; i < dim; ++i) r[i] *= phi;
}

/// The forward map of one case: solve (warm-started from the last success), observe, and chain
/// the Jacobian. Holds the warm state behind a mutex; the cost function itself is stateless.

std::unique_ptr<ceres::LossFunction> MakeLoss(RobustLoss loss, double scale) {
  switch (loss) {
    case RobustLoss::kNone: return nullptr;
    case RobustLoss::kHuber: return std::make_unique<ceres::HuberLoss>(scale);
    case RobustLoss::kCauchy: return std::make_unique<ceres::CauchyLoss>(scale);
    case RobustLoss::kSoftL1: return std::make_unique<ceres::SoftLOneLoss>(scale);
  }
  return nullptr;
}

CaseEvaluator::CaseEvaluator(const FitInput& in, int case_index, std::vector<Fitted> fitted,
              const ceres::LossFunction* loss)
    : in_(in), case_(in.cases[case_index]), measurements_(case_.measurements),
      fitted_(std::move(fitted)), loss_(loss), statics_(in.statics) {
  const int m = static_cast<int>(fitted_.size());
  const std::vector<Nuisance> all = Nuisances(in, m);
  num_columns_ = m + NuisanceColumns(all);
  for (const Nuisance& n : all)
    if (n.case_index == case_index) own_nuisances_.push_back(n);
  for (const Fitted& f : fitted_) {
    CriticalTwistParameter p = CriticalTwistParameter::Stiffness(false, false, false, false);
    for (Stiffness st : f.drives) {
      p.bend1 = p.bend1 || st == Stiffness::kBend1;
      p.bend2 = p.bend2 || st == Stiffness::kBend2;
      p.twist = p.twist || st == Stiffness::kTwist;
      p.stretch = p.stretch || st == Stiffness::kStretch;
    }
    if (f.spring) {
      p.kind = CriticalTwistParameter::Kind::kSpring;
      p.spring = f.spring_zone_name;
    }
    column_terms_.push_back(p);  // a ring parameter scales none of the rod's terms
  }
  // Another case's nuisance moves nothing here (its own columns are set per evaluation).
  column_terms_.resize(num_columns_,
                       CriticalTwistParameter::Stiffness(false, false, false, false));
  bool reads_frames = false;
  for (const auto& meas : measurements_) {
    num_residuals_ += meas->num_residuals();
    needs_reactions_ = needs_reactions_ || meas->needs_reactions();
    needs_section_ = needs_section_ || meas->needs_section();
    needs_state_ = needs_state_ || meas->needs_state();
    reads_frames = reads_frames || meas->reads_held_frames();
  }
  // The reactions' and the section's derivatives by a held frame's turn, and those of a
  // measurement that reads the frames themselves, are not modelled: refused, not approximated.
  bool rotation = false, moved = false;  // a held frame turned; a held point or gravity moved
  for (const Nuisance& n : own_nuisances_)
    (n.kind == Nuisance::Kind::kRotation ? rotation : moved) = true;
  if (rotation && (needs_reactions_ || needs_section_ || reads_frames))
    throw std::invalid_argument(
        "case " + case_.load_case.name +
        ": rotation_prior_deg (a fitted clamp frame) is not supported with reaction, force, "
        "surface point or roll marker observations of the same case");
  // A moved held point or a turned gravity: the derivatives of the critical twist, the
  // reactions, the section and the roll by them are not modelled; nor are those of moment loads
  // (no part of the Hessian) or of a mirror plane (which a moved point or gravity breaks).
  if (moved) {
    const LoadCase& lc = case_.load_case;
    const char* what = nullptr;
    if (needs_state_ || needs_reactions_ || needs_section_ || reads_frames)
      what = "critical twist, reaction, force, surface point or roll marker observations";
    else if (lc.symmetry)
      what = "a symmetry plane";
    for (const Nuisance& n : own_nuisances_)
      if (n.kind == Nuisance::Kind::kPosition &&
          (!lc.point_moments.empty() || !lc.tip_moment.isZero() ||
           !lc.tip_moment_follower.isZero()))
        what = "moment loads";
    if (what)
      throw std::invalid_argument("case " + lc.name +
                                  ": position_prior and gravity_prior_deg (a fitted held point "
                                  "or gravity) are not supported with " + what +
                                  " in the same case");
  }
}

// Solve, derivatives, measurements: they share the solved state, the kept factor and the timing;
// each measurement evaluates itself (measurement.h).
bool CaseEvaluator::Evaluate(const double* logp, double* residuals, double* jacobian, Mat3X* shape,
              RodState* final_state) const {
  const Material material = MaterialAt(in_, fitted_, logp);
  const LoadCase load_case =
      own_nuisances_.empty() ? case_.load_case : WithNuisances(case_.load_case, own_nuisances_, logp);
  const Vec3 gravity = GravityWithNuisances(in_.gravity, own_nuisances_, logp);
  std::shared_ptr<const RodModel> model;
  try {
    model = std::make_shared<const RodModel>(in_.rod, material, gravity, load_case,
                                             in_.springs);
  } catch (const std::invalid_argument&) {
    return false;
  }
  // The warm state and the kept factor of this case's last solve (one workspace per case: a
  // parameter change reuses the factor for chord steps, a repeat evaluation converges at once).
  RodState state;
  StaticsWorkspace ws;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    state = has_warm_ ? warm_ : StartState(*model, nullptr);
    ws = workspace_;
  }
  Clock::time_point t0 = Clock::now();
  Scene scene;
  scene.rod = in_.rod;
  scene.material = material;
  scene.gravity = gravity;
  scene.springs = in_.springs;
  CaseSolution solved = SolveModel(model, scene, nullptr, statics_, &ws, &state);
  if (!(solved.ok() && solved.summary.stable)) {  // a warm start can mislead: retry from the start
    RodState start = StartState(*model, nullptr);
    ws = StaticsWorkspace();
    solved = SolveModel(model, scene, nullptr, statics_, &ws, &start);
  }
  state = solved.state;
  const StaticsSummary& summary = solved.summary;
  Charge(&timing_.solve, &t0);
  ++timing_.solves;
  if (!(summary.converged && summary.stable)) {
    std::lock_guard<std::mutex> lock(mutex_);
    last_failure_ = "case " + case_.load_case.name + ": " +
                    (summary.converged ? "the equilibrium found is unstable" : summary.reason);
    data_failure_ = false;
    return false;
  }
  Derivatives d;
  d.column_terms = column_terms_;
  if (jacobian) {
    if (!Differentiate(*model, state, ws, logp, &d)) return false;
    Charge(&timing_.jacobian, &t0);
  }
  PokeResult poke;
  std::vector<Eigen::Matrix3Xd> d_ring;
  if (needs_section_ && !SolveSection(*model, state, material, &poke, jacobian ? &d_ring : nullptr))
    return false;
  SolvedCase view;
  view.x = &state.x;
  view.model = model.get();
  view.state = &state;
  view.reactions = &solved.reactions;
  view.poke = &poke;
  view.num_parameters = num_columns_;
  if (jacobian) {
    view.d_x = &d.dx;
    view.d_q = &d.dq;
    view.d_reactions = &d.d_reactions;
    view.d_ring = &d_ring;
    view.parameters = &d.column_terms;
  }
  if (!EvaluateMeasurements(view, residuals, jacobian)) return false;
  Charge(&timing_.observation, &t0);
  if (!AllFinite(residuals, jacobian)) return false;
  // The trust-region minimizer asks for the Jacobian only at the iterates it accepts (and at
  // the start): trial steps start from the last iterate's state but do not replace it, so a
  // rejected trial that slipped onto another equilibrium (an extra twist turn, a flipped
  // loop) cannot carry the fit onto that branch.
  if (jacobian) {
    std::lock_guard<std::mutex> lock(mutex_);
    warm_ = state;
    has_warm_ = true;
    workspace_ = ws;
  }
  if (shape) *shape = state.x;
  if (final_state) *final_state = state;
  return true;
}

// One unit-term gradient per parameter: the terms of every stiffness it drives together (U is
// linear in each), so a tied bend_stiffness scales B1 and B2 alike, which keeps an isotropic rod
// isotropic (sensitivities after a twist-eliminated solve need no full Hessian then,
// sensitivity.cc).
void CaseEvaluator::UnitTerms(std::vector<EnergyTerms>* terms, std::vector<int>* owner) const {
  const int m = static_cast<int>(fitted_.size());
  for (int k = 0; k < m; ++k) {
    if (!fitted_[k].drives.empty()) {
      EnergyTerms unit = EnergyTerms::Only(-1);
      for (Stiffness st : fitted_[k].drives) {
        switch (st) {
          case Stiffness::kBend1: unit.bend1 = 1.0; break;
          case Stiffness::kBend2: unit.bend2 = 1.0; break;
          case Stiffness::kTwist: unit.twist = 1.0; break;
          case Stiffness::kStretch: unit.stretch = 1.0; break;
        }
      }
      terms->push_back(unit);
      owner->push_back(k);
    }
    if (fitted_[k].spring) {
      terms->push_back(EnergyTerms::OnlySprings(&fitted_[k].spring_zone_name));
      owner->push_back(k);
    }
  }
  if (fixed_columns_) {
    // What the fit would cost without skipping the fixed stiffnesses: their columns are
    // computed alongside (same factor, one back-substitution each) and dropped.
    for (int st = 0; st < 4; ++st) {
      bool driven = false;
      for (const Fitted& f : fitted_)
        for (Stiffness d : f.drives) driven = driven || static_cast<int>(d) == st;
      if (!driven) terms->push_back(EnergyTerms::Only(st));
    }
  }
}

// The derivatives of the equilibrium by the material's columns (one unit-term gradient each) and
// by this case's nuisances, then of the vertices and the held points' reactions.
bool CaseEvaluator::Differentiate(const RodModel& model, const RodState& state,
                                  const StaticsWorkspace& ws, const double* logp,
                                  Derivatives* d) const {
  const int m = static_cast<int>(fitted_.size());  // the material's columns
  const int M = num_columns_;                        // and every case's nuisances
  std::vector<EnergyTerms> terms;
  std::vector<int> owner;
  UnitTerms(&terms, &owner);
  const size_t fitted_terms = owner.size();
  Eigen::MatrixXd dq_terms;
  Eigen::MatrixXd dq = Eigen::MatrixXd::Zero(model.num_free_dofs(), M);
  if (!terms.empty()) {  // ring parameters alone leave the rod unchanged
    if (!TermSensitivities(model, state, ws, terms, &dq_terms)) return false;
    for (size_t t = 0; t < fitted_terms; ++t) dq.col(owner[t]) += dq_terms.col(static_cast<int>(t));
  }
  if (!NuisanceSensitivities(model, state, ws, logp, &dq, &d->column_terms)) return false;
  terms.resize(fitted_terms);
  d->dx = VertexSensitivities(model, dq);
  // The clamp's point, vertex 0, is no dof: its offset moves it.
  for (const Nuisance& n : own_nuisances_)
    if (n.kind == Nuisance::Kind::kPosition && n.held == "clamp")
      d->dx.block<3, 3>(0, n.first_column).setIdentity();
  if (needs_state_) d->dq = dq;
  if (needs_reactions_) {
    // The reactions' derivatives: the unconstrained unit gradients at fixed q (held rows
    // included), the equilibrium's dq, and which spring zones each parameter stiffens.
    Eigen::MatrixXd dr = Eigen::MatrixXd::Zero(model.num_free_dofs(), M);
    for (size_t t = 0; t < terms.size(); ++t) {
      EnergyTerms unit = terms[t];
      unit.hold = false;
      VecX gu;
      AssembleGradient(model, state, unit, &gu);
      dr.col(owner[t]) += gu;
    }
    std::vector<std::vector<int>> zones(M);
    for (int k = 0; k < m; ++k)
      if (fitted_[k].spring)
        for (int z = 0; z < model.num_spring_zones(); ++z)
          if (model.spring_zone(z).parameter == fitted_[k].spring_zone_name) zones[k].push_back(z);
    d->d_reactions = HeldReactionDerivatives(model, state, dq, dr, zones);
  }
  return true;
}

// This case's nuisance columns of dq. Its held frames: d phi_k turns the frame about the world
// axis J_l(phi) e_k at the held point, whose gradient change is exact (ClampTurnGradients);
// dq = -H^-1 dg. A held point's offset d: its held rows move by d, the rest answer -H^-1 dg/dd
// (HeldPointOffsetGradients). Gravity's tilt: its dead loads' change (GravityTiltGradients),
// which keeps an isotropic rod untwisted like any dead load.
bool CaseEvaluator::NuisanceSensitivities(const RodModel& model, const RodState& state,
                                          const StaticsWorkspace& ws, const double* logp,
                                          Eigen::MatrixXd* dq,
                                          std::vector<CriticalTwistParameter>* column_terms) const {
  for (const Nuisance& n : own_nuisances_) {
    if (n.kind == Nuisance::Kind::kPosition) {
      Eigen::MatrixXd dg_offset, dq_offset;
      std::vector<int> moved;
      HeldPointOffsetGradients(model, state, n, &dg_offset, &moved);
      if (!GradientSensitivities(model, state, ws, dg_offset, /*keeps_isotropy=*/false,
                                 &dq_offset))
        return false;
      for (int d : moved) dq_offset.middleRows<3>(d).setIdentity();
      dq->middleCols(n.first_column, 3) = dq_offset;
      continue;
    }
    if (n.kind == Nuisance::Kind::kGravity) {
      const Eigen::Matrix<double, 3, 2> B = GravityTiltBasis(in_.gravity);
      const Eigen::Matrix<double, 3, 2> axes =
          RotationLeftJacobian(B * Eigen::Vector2d(logp[n.first_column],
                                                   logp[n.first_column + 1])) * B;
      Eigen::MatrixXd dg_tilt, dq_tilt;
      GravityTiltGradients(model, axes, &dg_tilt);
      if (!GradientSensitivities(model, state, ws, dg_tilt, /*keeps_isotropy=*/true, &dq_tilt))
        return false;
      dq->middleCols(n.first_column, 2) = dq_tilt;
      continue;
    }
    const Eigen::Matrix3d Jl = RotationLeftJacobian(
        Vec3(logp[n.first_column], logp[n.first_column + 1], logp[n.first_column + 2]));
    Eigen::MatrixXd dg_turn, dq_phi;
    ClampTurnGradients(model, state, n.end_clamp, &dg_turn);
    if (!GradientSensitivities(model, state, ws, dg_turn * Jl, /*keeps_isotropy=*/false,
                               &dq_phi))
      return false;
    dq->middleCols(n.first_column, 3) = dq_phi;
    for (int k = 0; k < 3; ++k)
      (*column_terms)[n.first_column + k] =
          CriticalTwistParameter::Rotation(n.end_clamp, Jl.col(k));
  }
  return true;
}

bool CaseEvaluator::EvaluateMeasurements(const SolvedCase& view, double* residuals,
                                         double* jacobian) const {
  const int M = num_columns_;
  int row = 0;
  for (const auto& meas : measurements_) {
    double* r = residuals + row;
    double* J = jacobian ? jacobian + row * M : nullptr;
    std::string why;
    if (!meas->Evaluate(view, r, J, &why)) {
      // The data, not the solve (a point behind the camera), so the message names the entry.
      std::lock_guard<std::mutex> lock(mutex_);
      last_failure_ = "case " + case_.load_case.name + ": " + meas->label() + ": " + why;
      data_failure_ = true;
      return false;
    }
    // Per measurement: the loss sees each marker's, point's or reading's residual vector.
    for (int k = 0, k_row = 0; k < meas->num_measurements(); ++k) {
      const int dim = meas->measurement_rows(k);
      ApplyLoss(loss_, dim, r + k_row, J ? J + k_row * M : nullptr, M);
      k_row += dim;
    }
    row += meas->num_residuals();
  }
  return true;
}

// False, with the failure recorded, when a residual or a Jacobian entry is not finite.
bool CaseEvaluator::AllFinite(const double* residuals, const double* jacobian) const {
  const int m = num_parameters();
  for (int i = 0; i < num_residuals_; ++i) {
    bool finite = std::isfinite(residuals[i]);
    for (int c = 0; finite && jacobian && c < m; ++c) finite = std::isfinite(jacobian[i * m + c]);
    if (!finite) {
      // A value beyond what a double can weigh (a reading of 1e308 N, a sigma of 1e-320): bad
      // data, named by its observation; Ceres would only report a NaN gradient.
      std::lock_guard<std::mutex> lock(mutex_);
      last_failure_ = "case " + case_.load_case.name + ": " + ResidualLabel(i) +
                      ": a residual or its derivative is not finite (a value too large or a "
                      "sigma too small?)";
      data_failure_ = true;
      return false;
    }
  }
  return true;
}

std::string CaseEvaluator::ResidualLabel(int i) const {
  int row = 0;
  for (const auto& meas : measurements_) {
    for (int k = 0; k < meas->num_measurements(); ++k) {
      row += meas->measurement_rows(k);
      if (i < row) return meas->measurement_label(k);
    }
  }
  return "a residual";
}

bool CaseEvaluator::SolveSection(const RodModel& model, const RodState& state,
                                 const Material& material, PokeResult* poke,
                                 std::vector<Eigen::Matrix3Xd>* d_ring) const {
  try {
    *poke = SolvePoke(model, state, *in_.section,
                      RingStiffness{material.ring_bend_stiffness, material.ring_stretch_stiffness});
  } catch (const std::invalid_argument& e) {
    std::lock_guard<std::mutex> lock(mutex_);
    last_failure_ = "case " + case_.load_case.name + ": the poked section: " + e.what();
    data_failure_ = false;
    return false;
  }
  if (!poke->ring.summary.converged) {
    std::lock_guard<std::mutex> lock(mutex_);
    last_failure_ = "case " + case_.load_case.name + ": the poked section's ring did not converge (" +
                    poke->ring.summary.BriefReport() + ")";
    data_failure_ = false;
    return false;
  }
  if (!d_ring) return true;
  // d (world node) / d log p per fitted column, as a closed polyline (node 0 again at the end):
  // the ring's d nodes / d log k in section coordinates mapped to the world by d1, d2.
  const int n = static_cast<int>(poke->deformed_world.cols());
  const SectionPlacement& pl = poke->placement;
  d_ring->clear();
  for (const Fitted& f : fitted_) {
    Eigen::Matrix3Xd d = Eigen::Matrix3Xd::Zero(3, n + 1);
    if (f.ring != 0) {
      const Eigen::VectorXd& dn =
          f.ring == 1 ? poke->ring.d_nodes_d_log_bend : poke->ring.d_nodes_d_log_stretch;
      if (dn.size() != 2 * n) {  // an unstable ring equilibrium: no sensitivity
        std::lock_guard<std::mutex> lock(mutex_);
        last_failure_ = "case " + case_.load_case.name +
                        ": the poked section's ring equilibrium is unstable (no sensitivity)";
        data_failure_ = false;
        return false;
      }
      for (int j = 0; j <= n; ++j) {
        const int k = j % n;
        d.col(j) = dn[NodeDof(k)] * pl.d1 + dn[NodeDof(k) + 1] * pl.d2;
      }
    }
    d_ring->push_back(d);
  }
  return true;
}

bool AllCasesCost::Evaluate(double const* const* parameters, double* residuals,
              double** jacobians) const {
  const int n = static_cast<int>(cases_.size());
  const int m = parameter_block_sizes()[0];
  double* jacobian = jacobians ? jacobians[0] : nullptr;
  std::atomic<int> next{0};
  std::atomic<bool> ok{true};
  auto work = [&]() {
    for (int c = next++; c < n; c = next++) {
      bool done = false;
      try {
        done = cases_[c]->Evaluate(parameters[0], residuals + first_row_[c],
                                   jacobian ? jacobian + first_row_[c] * m : nullptr, nullptr);
      } catch (const std::exception&) {
        done = false;  // e.g. out of memory in one case: a failed evaluation, not a crash
      }
      if (!done) ok = false;  // a failed solve: Ceres then shortens the step
    }
  };
  std::vector<std::thread> helpers;
  for (int t = 1; t < std::min(num_threads_, n); ++t) helpers.emplace_back(work);
  work();
  for (std::thread& t : helpers) t.join();
  return ok;
}

}  // namespace fit_internal
}  // namespace rodfit
