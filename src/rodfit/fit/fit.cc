// Identification (fit.h): the Ceres problem, its cost per case, the NLopt global start,
// covariance and identifiability.
#include "rodfit/fit/fit.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <thread>
#include <sstream>
#include <stdexcept>

#include <Eigen/SVD>
#include <ceres/ceres.h>
#include <nlopt.hpp>

#include "rodfit/fit/identifiability.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/poke.h"
#include "rodfit/solve/reactions.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/sensitivity.h"
#include "rodfit/solve/statics.h"

namespace rodfit {
namespace {

using Clock = std::chrono::steady_clock;

/// A fitted parameter: where it sits in FitInput::parameters and which stiffnesses it drives
/// (bend_stiffness drives B2 too when bend_stiffness_2 is absent: the isotropic tie).
struct Fitted {
  int input_index = 0;
  std::string name;
  std::vector<Stiffness> drives;  ///< rod stiffnesses it sets
  bool spring = false;            ///< a spring stiffness: drives the zones of `spring_zone_name`
  std::string spring_zone_name;   ///< "" for spring_stiffness, else the zone parameter
  int ring = 0;                   ///< 1: ring_bend_stiffness, 2: ring_stretch_stiffness
};

int NumSurfacePoints(const FitCase& c) {
  int n = 0;
  for (const SurfacePoints& sp : c.surface_points) n += static_cast<int>(sp.points.size());
  return n;
}

// What `surface_points` need and what they can determine (fit.h).
void CheckSurfacePoints(const FitInput& in, const std::vector<Fitted>& fitted) {
  bool any = false;
  for (const FitCase& c : in.cases) {
    if (c.surface_points.empty()) continue;
    any = true;
    if (!c.load_case.poke)
      throw std::invalid_argument("case " + c.load_case.name + ": surface_points without a poke");
    if (!in.section)
      throw std::invalid_argument("case " + c.load_case.name +
                                  ": surface_points need the cross-section model (section:)");
    for (const SurfacePoints& sp : c.surface_points)
      if (!(sp.sigma > 0) || sp.points.empty())
        throw std::invalid_argument("case " + c.load_case.name + ": " + sp.label +
                                    ": needs points and sigma > 0");
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

std::vector<Fitted> FittedParameters(const FitInput& in) {
  std::vector<Fitted> out;
  const bool tied = !in.material.bend_stiffness_2.has_value();
  for (size_t k = 0; k < in.parameters.size(); ++k) {
    const FitParameter& p = in.parameters[k];
    if (!p.fit) continue;
    Fitted f;
    f.input_index = static_cast<int>(k);
    f.name = p.name;
    if (p.name == "bend_stiffness") {
      f.drives = {Stiffness::kBend1};
      if (tied) f.drives.push_back(Stiffness::kBend2);
    } else if (p.name == "bend_stiffness_2") {
      if (tied) throw std::invalid_argument("bend_stiffness_2: fitted but tied to bend_stiffness");
      f.drives = {Stiffness::kBend2};
    } else if (p.name == "twist_stiffness") {
      f.drives = {Stiffness::kTwist};
    } else if (p.name == "stretch_stiffness") {
      f.drives = {Stiffness::kStretch};
    } else if (p.name == "ring_bend_stiffness" || p.name == "ring_stretch_stiffness") {
      f.ring = p.name == "ring_bend_stiffness" ? 1 : 2;
    } else if (p.name == "spring_stiffness" || in.material.spring_parameters.count(p.name)) {
      f.spring = true;
      f.spring_zone_name = p.name == "spring_stiffness" ? "" : p.name;
      if (in.springs.empty())
        throw std::invalid_argument(p.name +
                                    ": fitted, but the scene has no springs for it to act on");
      if (!ZonesUse(in, f.spring_zone_name))
        throw std::invalid_argument(p.name + ": fitted, but no spring zone uses it");
    } else {
      throw std::invalid_argument(p.name + ": not a parameter of the rod model");
    }
    out.push_back(f);
  }
  CheckSurfacePoints(in, out);
  return out;
}

Material MaterialAt(const FitInput& in, const std::vector<Fitted>& fitted, const double* logp) {
  Material m = in.material;
  for (size_t k = 0; k < fitted.size(); ++k) {
    const double v = std::exp(logp[k]);
    const std::string& name = fitted[k].name;
    if (name == "bend_stiffness") m.bend_stiffness = v;
    if (name == "bend_stiffness_2") m.bend_stiffness_2 = v;
    if (name == "twist_stiffness") m.twist_stiffness = v;
    if (name == "stretch_stiffness") m.stretch_stiffness = v;
    if (name == "ring_bend_stiffness") m.ring_bend_stiffness = v;
    if (name == "ring_stretch_stiffness") m.ring_stretch_stiffness = v;
    if (fitted[k].spring) {
      if (fitted[k].spring_zone_name.empty()) m.spring_stiffness = v;
      else m.spring_parameters[fitted[k].spring_zone_name] = v;
    }
  }
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
class CaseEvaluator {
 public:
  CaseEvaluator(const FitInput& in, int case_index, std::vector<Fitted> fitted,
                const ceres::LossFunction* loss)
      : in_(in), case_(in.cases[case_index]), fitted_(std::move(fitted)), loss_(loss),
        statics_(in.statics) {
    for (const auto& obs : case_.observations) num_residuals_ += obs->num_residuals();
    for (const ForceMeasurement& f : case_.grasp_forces) num_residuals_ += f.num_residuals();
    num_residuals_ += 3 * NumSurfacePoints(case_);
  }

  /// FitOptions::jacobian_of_fixed_parameters: also compute the fixed stiffnesses' columns.
  void ComputeFixedColumns(bool on) { fixed_columns_ = on; }

  /// The warm start: the state to start from before the first evaluation (the case's start,
  /// e.g. the previous case's solution at the start values).
  void SetWarmStart(const RodState& state) {
    std::lock_guard<std::mutex> lock(mutex_);
    warm_ = state;
    has_warm_ = true;
  }

  /// The state of the last accepted iterate (or the start), if any.
  std::optional<RodState> WarmState() const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!has_warm_) return std::nullopt;
    return warm_;
  }

  int num_residuals() const { return num_residuals_; }
  int num_parameters() const { return static_cast<int>(fitted_.size()); }

  struct Timing {
    double solve = 0, jacobian = 0, observation = 0;
    int solves = 0;
  };
  Timing timing() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return timing_;
  }
  /// Why the last failed evaluation failed (empty if none did), and whether the data failed
  /// (an observation that cannot be evaluated on the solved shape) rather than the solve.
  std::string last_failure(bool* data = nullptr) const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (data) *data = data_failure_;
    return last_failure_;
  }

  /// residuals: num_residuals(); jacobian (row major num_residuals x m) optional.
  /// `final_state`, when given, receives the equilibrium (the report's poked section needs it).
  bool Evaluate(const double* logp, double* residuals, double* jacobian, Mat3X* shape,
                RodState* final_state = nullptr) const {
    const Material material = MaterialAt(in_, fitted_, logp);
    std::shared_ptr<const RodModel> model;
    try {
      model = std::make_shared<const RodModel>(in_.rod, material, in_.gravity, case_.load_case,
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
    scene.gravity = in_.gravity;
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
    const int m = num_parameters();
    Eigen::MatrixXd dx;
    // Per measured holder: d(reaction) / d log p, 6 x m (force rows, then moment rows).
    std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> d_reactions;
    if (jacobian) {
      // One unit-term gradient per parameter: the terms of every stiffness it drives together
      // (U is linear in each), so a tied bend_stiffness scales B1 and B2 alike, which keeps an
      // isotropic rod isotropic (sensitivities after a twist-eliminated solve need no full
      // Hessian then, sensitivity.cc).
      std::vector<EnergyTerms> terms;
      std::vector<int> owner;
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
          terms.push_back(unit);
          owner.push_back(k);
        }
        if (fitted_[k].spring) {
          terms.push_back(EnergyTerms::OnlySprings(&fitted_[k].spring_zone_name));
          owner.push_back(k);
        }
      }
      const size_t fitted_terms = terms.size();
      if (fixed_columns_) {
        // What the fit would cost without skipping the fixed stiffnesses: their columns are
        // computed alongside (same factor, one back-substitution each) and dropped.
        for (int st = 0; st < 4; ++st) {
          bool driven = false;
          for (const Fitted& f : fitted_)
            for (Stiffness d : f.drives) driven = driven || static_cast<int>(d) == st;
          if (!driven) terms.push_back(EnergyTerms::Only(st));
        }
      }
      Eigen::MatrixXd dq_terms;
      Eigen::MatrixXd dq = Eigen::MatrixXd::Zero(model->num_free_dofs(), m);
      if (!terms.empty()) {  // ring parameters alone leave the rod unchanged
        if (!TermSensitivities(*model, state, ws, terms, &dq_terms)) return false;
        for (size_t t = 0; t < fitted_terms; ++t) dq.col(owner[t]) += dq_terms.col(static_cast<int>(t));
      }
      terms.resize(fitted_terms);
      dx = VertexSensitivities(*model, dq);
      if (!case_.grasp_forces.empty()) {
        // The reactions' derivatives: the unconstrained unit gradients at fixed q (held rows
        // included), the equilibrium's dq, and which spring zones each parameter stiffens.
        Eigen::MatrixXd dr = Eigen::MatrixXd::Zero(model->num_free_dofs(), m);
        for (size_t t = 0; t < terms.size(); ++t) {
          EnergyTerms unit = terms[t];
          unit.hold = false;
          VecX gu;
          AssembleGradient(*model, state, unit, &gu);
          dr.col(owner[t]) += gu;
        }
        std::vector<std::vector<int>> zones(m);
        for (int k = 0; k < m; ++k)
          if (fitted_[k].spring)
            for (int z = 0; z < model->num_spring_zones(); ++z)
              if (model->spring_zone(z).parameter == fitted_[k].spring_zone_name) zones[k].push_back(z);
        d_reactions = HeldReactionDerivatives(*model, state, dq, dr, zones);
      }
      Charge(&timing_.jacobian, &t0);
    }
    int row = 0;
    for (size_t o = 0; o < case_.observations.size(); ++o) {
      const auto& obs = case_.observations[o];
      VecX r;
      VertexJacobian J;
      if (!obs->Evaluate(state.x, &r, jacobian ? &J : nullptr)) {
        // A projection that fails (a point behind the camera) or a non-finite residual: the
        // data, not the solve, so the message names the observation.
        std::lock_guard<std::mutex> lock(mutex_);
        last_failure_ = "case " + case_.load_case.name + ": " +
                        (o < case_.labels.size() ? case_.labels[o] : obs->type()) +
                        ": the observation model cannot be evaluated on the solved shape (a point "
                        "behind the camera, or a non-finite residual)";
        data_failure_ = true;
        return false;
      }
      Eigen::MatrixXd Jp;
      if (jacobian) Jp = J.Multiply(dx);
      // Per measurement: the loss sees each marker's / point's residual vector.
      const int dim = obs->num_residuals() / std::max(1, obs->num_measurements());
      for (int k = 0; k < obs->num_measurements(); ++k) {
        double* rk = residuals + row + k * dim;
        for (int i = 0; i < dim; ++i) rk[i] = r[k * dim + i];
        double* Jk = jacobian ? jacobian + (row + k * dim) * m : nullptr;
        if (Jk)
          for (int i = 0; i < dim; ++i)
            for (int c = 0; c < m; ++c) Jk[i * m + c] = Jp(k * dim + i, c);
        ApplyLoss(loss_, dim, rk, Jk, m);
      }
      row += obs->num_residuals();
    }
    if (!case_.grasp_forces.empty()) {
      for (const ForceMeasurement& f : case_.grasp_forces) {
        int which = -1;
        for (size_t h = 0; h < solved.reactions.size(); ++h)
          if (solved.reactions[h].point == f.point) which = static_cast<int>(h);
        if (which < 0) return false;  // CheckReactions refuses this up front
        const HeldReaction& reaction = solved.reactions[which];
        const int dim = f.num_residuals();
        double* rk = residuals + row;
        for (int i = 0; i < 3; ++i) rk[i] = (reaction.force[i] - f.force[i]) / f.sigma;
        if (f.moment)
          for (int i = 0; i < 3; ++i) rk[3 + i] = (reaction.moment[i] - (*f.moment)[i]) / f.sigma_moment;
        double* Jk = jacobian ? jacobian + row * m : nullptr;
        if (Jk)
          for (int i = 0; i < dim; ++i)
            for (int c = 0; c < m; ++c)
              Jk[i * m + c] = d_reactions[which](i, c) / (i < 3 ? f.sigma : f.sigma_moment);
        ApplyLoss(loss_, dim, rk, Jk, m);
        row += dim;
      }
    }
    if (!case_.surface_points.empty() &&
        !SurfaceResiduals(*model, state, material, residuals, jacobian, &row))
      return false;
    Charge(&timing_.observation, &t0);
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

 private:
  // The observation (or force reading, or surface point set) that residual row i belongs to.
  std::string ResidualLabel(int i) const {
    int row = 0;
    for (size_t o = 0; o < case_.observations.size(); ++o) {
      row += case_.observations[o]->num_residuals();
      if (i < row) return o < case_.labels.size() ? case_.labels[o] : case_.observations[o]->type();
    }
    for (const ForceMeasurement& f : case_.grasp_forces) {
      row += f.num_residuals();
      if (i < row) return f.label;
    }
    for (const SurfacePoints& sp : case_.surface_points) {
      row += 3 * static_cast<int>(sp.points.size());
      if (i < row) return sp.label;
    }
    return "a residual";
  }

  // The case's surface points against the deformed ring of its poke (fit.h SurfacePoints), rows
  // from *row on. Only ring parameters have non-zero columns (CheckSurfacePoints refuses rod
  // parameters together with surface points): the ring's d nodes / d log k in section
  // coordinates, mapped to the world by the placement's d1, d2 and chained through the foot.
  bool SurfaceResiduals(const RodModel& model, const RodState& state, const Material& material,
                        double* residuals, double* jacobian, int* row) const {
    const int m = num_parameters();
    PokeResult poke;
    try {
      poke = SolvePoke(model, state, *in_.section,
                       RingStiffness{material.ring_bend_stiffness, material.ring_stretch_stiffness});
    } catch (const std::invalid_argument&) {
      return false;
    }
    if (!poke.ring.summary.converged) return false;
    const int n = static_cast<int>(poke.deformed_world.cols());
    // The closed ring as a polyline: node 0 repeated at the end (polyline vertex j is node j % n).
    Eigen::Matrix3Xd ring(3, n + 1);
    ring.leftCols(n) = poke.deformed_world;
    ring.col(n) = poke.deformed_world.col(0);
    // d (world node) / d log p per fitted column: 3 x (n + 1) per column.
    std::vector<Eigen::Matrix3Xd> d_ring;
    if (jacobian) {
      const SectionPlacement& pl = poke.placement;
      for (int c = 0; c < m; ++c) {
        Eigen::Matrix3Xd d = Eigen::Matrix3Xd::Zero(3, n + 1);
        if (fitted_[c].ring != 0) {
          const Eigen::VectorXd& dn = fitted_[c].ring == 1 ? poke.ring.d_nodes_d_log_bend
                                                           : poke.ring.d_nodes_d_log_stretch;
          if (dn.size() != 2 * n) return false;  // an unstable ring equilibrium: no sensitivity
          for (int j = 0; j <= n; ++j) {
            const int k = j % n;
            d.col(j) = dn[NodeDof(k)] * pl.d1 + dn[NodeDof(k) + 1] * pl.d2;
          }
        }
        d_ring.push_back(d);
      }
    }
    for (const SurfacePoints& sp : case_.surface_points) {
      for (const Eigen::Vector3d& q : sp.points) {
        const PolylineFoot foot = ClosestPointOnPolyline<3>(ring, q);
        if (foot.edge < 0) return false;
        Eigen::Vector3d p;
        double t = 0.0;
        Eigen::Vector3d a = Eigen::Vector3d::Zero(), e = Eigen::Vector3d::Zero();
        if (foot.vertex >= 0) {
          p = ring.col(foot.vertex);
        } else {
          a = ring.col(foot.edge);
          e = ring.col(foot.edge + 1) - a;
          t = (q - a).dot(e) / e.squaredNorm();
          p = a + t * e;
        }
        double* rk = residuals + *row;
        for (int i = 0; i < 3; ++i) rk[i] = (p[i] - q[i]) / sp.sigma;
        double* Jk = jacobian ? jacobian + *row * m : nullptr;
        if (Jk) {
          for (int c = 0; c < m; ++c) {
            Eigen::Vector3d dp;
            if (foot.vertex >= 0) {
              dp = d_ring[c].col(foot.vertex);
            } else {
              // p = a + t e, t = (q - a).e / |e|^2:
              // dt = (-da.e + (q - a).de - 2 t e.de) / |e|^2, dp = da + dt e + t de.
              const Eigen::Vector3d da = d_ring[c].col(foot.edge);
              const Eigen::Vector3d de = d_ring[c].col(foot.edge + 1) - da;
              const double dt = (-da.dot(e) + (q - a).dot(de) - 2.0 * t * e.dot(de)) /
                                e.squaredNorm();
              dp = da + dt * e + t * de;
            }
            for (int i = 0; i < 3; ++i) Jk[i * m + c] = dp[i] / sp.sigma;
          }
        }
        ApplyLoss(loss_, 3, rk, Jk, m);
        *row += 3;
      }
    }
    return true;
  }

  const FitInput& in_;
  const FitCase& case_;
  std::vector<Fitted> fitted_;
  const ceres::LossFunction* loss_;
  int num_residuals_ = 0;
  mutable std::mutex mutex_;  // guards the warm start only; evaluation is otherwise pure
  mutable RodState warm_;
  mutable bool has_warm_ = false;
  mutable StaticsWorkspace workspace_;  // the kept factor of the warm state
  StaticsOptions statics_;
  bool fixed_columns_ = false;
  mutable Timing timing_;  // accumulated under mutex_ by Charge
  mutable std::string last_failure_;
  mutable bool data_failure_ = false;

  void Charge(double* bucket, Clock::time_point* t0) const {
    const Clock::time_point now = Clock::now();
    std::lock_guard<std::mutex> lock(mutex_);
    *bucket += std::chrono::duration<double>(now - *t0).count();
    *t0 = now;
  }
};

/// Every case as one residual block, the cases evaluated on `num_threads` threads, each writing
/// its own rows. Ceres, on one thread, then sums cost and gradient over the rows in their fixed
/// order, so results do not depend on the thread count or on which thread took which case
/// (with a block per case, Ceres' per-thread partial sums changed the last digits; docs/cli.md,
/// "Reproducible outputs").
class AllCasesCost final : public ceres::CostFunction {
 public:
  AllCasesCost(std::vector<const CaseEvaluator*> cases, int num_threads)
      : cases_(std::move(cases)), num_threads_(std::max(1, num_threads)) {
    int rows = 0;
    for (const CaseEvaluator* c : cases_) {
      first_row_.push_back(rows);
      rows += c->num_residuals();
    }
    set_num_residuals(rows);
    mutable_parameter_block_sizes()->push_back(cases_.empty() ? 0 : cases_[0]->num_parameters());
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
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

 private:
  std::vector<const CaseEvaluator*> cases_;
  std::vector<int> first_row_;
  int num_threads_;
};

std::unique_ptr<ceres::LossFunction> MakeLoss(RobustLoss loss, double scale) {
  switch (loss) {
    case RobustLoss::kNone: return nullptr;
    case RobustLoss::kHuber: return std::make_unique<ceres::HuberLoss>(scale);
    case RobustLoss::kCauchy: return std::make_unique<ceres::CauchyLoss>(scale);
    case RobustLoss::kSoftL1: return std::make_unique<ceres::SoftLOneLoss>(scale);
  }
  return nullptr;
}

class ProgressCallback final : public ceres::IterationCallback {
 public:
  ProgressCallback(const FitOptions& o, Clock::time_point start) : o_(o), start_(start) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (o_.progress) {
      FitIterationInfo info;
      info.iteration = s.iteration;
      info.cost = s.cost;
      info.relative_decrease = s.cost > 0 ? s.cost_change / s.cost : 0.0;
      info.seconds = std::chrono::duration<double>(Clock::now() - start_).count();
      o_.progress(info);
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const FitOptions& o_;
  Clock::time_point start_;
};

// Every measured reaction names a point the case holds.
void CheckHeldPoints(const FitInput& in, const FitCase& c) {
  if (c.grasp_forces.empty()) return;
  std::vector<std::string> points = {"clamp"};
  try {
    const RodModel model(in.rod, in.material, in.gravity, c.load_case, in.springs);
    for (const HeldVertex& h : model.held()) points.push_back(h.Label());
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("case " + c.load_case.name + ": " + e.what());
  }
  for (const ForceMeasurement& f : c.grasp_forces) {
    if (std::find(points.begin(), points.end(), f.point) == points.end())
      throw std::invalid_argument("case " + c.load_case.name + ": " + f.label + ": the case holds no " +
                                  f.point);
    if (f.moment && f.point != "clamp" && f.point != "end_clamp")
      throw std::invalid_argument("case " + c.load_case.name + ": " + f.label +
                                  ": a moment is measured only at a clamp");
  }
}

// Solves every case once at the start values, in order, so that a case may start from the
// previous one's solution (`start: previous`) as `simulate` solves it; the solutions become
// the evaluators' warm starts. A case that fails here is left cold (its evaluation reports why).
void WarmStartsAtTheStart(const FitInput& in, const std::vector<Fitted>& fitted,
                          const std::vector<double>& logp,
                          const std::vector<std::unique_ptr<CaseEvaluator>>& evals) {
  Scene scene;
  scene.rod = in.rod;
  scene.material = MaterialAt(in, fitted, logp.data());
  scene.gravity = in.gravity;
  scene.springs = in.springs;
  std::optional<CaseSolution> previous;
  for (size_t c = 0; c < in.cases.size(); ++c) {
    std::optional<CaseSolution> solved;
    try {
      auto model = std::make_shared<const RodModel>(scene.rod, scene.material, scene.gravity,
                                                    in.cases[c].load_case, scene.springs);
      solved = SolveModel(model, scene, previous ? &*previous : nullptr, in.statics, nullptr,
                          nullptr);
    } catch (const std::invalid_argument&) {
    }
    if (solved && solved->ok()) evals[c]->SetWarmStart(solved->state);
    previous = std::move(solved);
  }
}

// Log-space search box of a fitted parameter: its bounds, or three decades around the start.
void SearchBox(const FitParameter& p, double* lo, double* hi) {
  *lo = p.min ? std::log(*p.min) : std::log(p.value) - 3.0 * std::log(10.0);
  *hi = p.max ? std::log(*p.max) : std::log(p.value) + 3.0 * std::log(10.0);
}

}  // namespace

bool FitOptions::Check(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(loss_scale > 0)) return fail("loss_scale must be > 0");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (global_evaluations < 1) return fail("global_evaluations must be >= 1");
  if (num_threads < 1) return fail("num_threads must be >= 1");
  if (!(max_log_std > 0)) return fail("max_log_std must be > 0");
  return true;
}

VarianceBand ResidualVarianceBand(int dof) {
  // Wilson–Hilferty: (chi2 / dof)^(1/3) is nearly normal with mean 1 - 2/(9 dof) and variance
  // 2/(9 dof). z = 3.0902 is the normal's 99.9 % quantile.
  const double nu = std::max(1, dof), z = 3.090232306167813;
  const double mean = 1.0 - 2.0 / (9.0 * nu), sd = std::sqrt(2.0 / (9.0 * nu));
  const double low = std::max(0.0, mean - z * sd), high = mean + z * sd;
  return {low * low * low, high * high * high};
}

const char* ParameterUnit(const std::string& name) {
  // The parameter table's unit (spring zones' own parameters: N/m^2, like spring_stiffness).
  return MaterialParameterUnit(name);
}

bool EvaluateForwardMap(const FitInput& input, const std::vector<double>& log_values,
                        Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian) {
  const std::vector<Fitted> fitted = FittedParameters(input);
  if (log_values.size() != fitted.size()) throw std::invalid_argument("log_values size");
  int total = 0;
  std::vector<std::unique_ptr<CaseEvaluator>> evals;
  for (size_t c = 0; c < input.cases.size(); ++c) {
    evals.push_back(std::make_unique<CaseEvaluator>(input, static_cast<int>(c), fitted, nullptr));
    total += evals.back()->num_residuals();
  }
  const int m = static_cast<int>(fitted.size());
  residuals->resize(total);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J(total, m);
  int row = 0;
  for (auto& e : evals) {
    if (!e->Evaluate(log_values.data(), residuals->data() + row,
                     jacobian ? J.data() + row * m : nullptr, nullptr))
      return false;
    row += e->num_residuals();
  }
  if (jacobian) *jacobian = J;
  return true;
}

FitResult Fit(const FitInput& input, const FitOptions& options) {
  const Clock::time_point start = Clock::now();
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("fit options: " + why);
  const std::vector<Fitted> fitted = FittedParameters(input);
  if (fitted.empty()) throw std::invalid_argument("parameters: nothing to fit (no `fit: true`)");
  const int m = static_cast<int>(fitted.size());
  std::vector<double> logp(m);
  for (int k = 0; k < m; ++k) {
    const FitParameter& p = input.parameters[fitted[k].input_index];
    if (!(p.value > 0)) throw std::invalid_argument(p.name + ": start value must be > 0");
    if (p.min && p.max && !(*p.min < *p.max))
      throw std::invalid_argument(p.name + ": min must be < max");
    if ((p.min && p.value < *p.min) || (p.max && p.value > *p.max))
      throw std::invalid_argument(p.name + ": start value outside [min, max]");
    logp[k] = std::log(p.value);
  }
  int total_residuals = 0;
  // Residuals that carry noise: a closest-point residual is perpendicular to the curve, so a
  // 3-D point (points3d, surface_points) carries 2 and a pixel of an image curve 1. The
  // residual variance 2 cost / (N - m) must count these, or it underestimates the noise and the
  // reported std by up to sqrt(3/2) (points) or sqrt(2) (pixels).
  int effective_residuals = 0;
  for (const FitCase& c : input.cases) {
    for (const auto& o : c.observations) {
      total_residuals += o->num_residuals();
      const bool curve = dynamic_cast<const Points3dObservation*>(o.get()) ||
                         dynamic_cast<const ImageCurveObservation*>(o.get());
      effective_residuals += o->num_residuals() - (curve ? o->num_measurements() : 0);
    }
    int force_residuals = 0;
    for (const ForceMeasurement& f : c.grasp_forces) force_residuals += f.num_residuals();
    effective_residuals += force_residuals + 2 * NumSurfacePoints(c);
    total_residuals += force_residuals + 3 * NumSurfacePoints(c);
    CheckHeldPoints(input, c);
  }
  if (total_residuals == 0) throw std::invalid_argument("cases: no observations to fit");
  if (total_residuals <= m)
    throw std::invalid_argument("cases: fewer residuals than fitted parameters");

  const std::unique_ptr<ceres::LossFunction> loss = MakeLoss(options.loss, options.loss_scale);
  std::vector<std::unique_ptr<CaseEvaluator>> evals;
  for (size_t c = 0; c < input.cases.size(); ++c) {
    evals.push_back(
        std::make_unique<CaseEvaluator>(input, static_cast<int>(c), fitted, loss.get()));
    evals.back()->ComputeFixedColumns(options.jacobian_of_fixed_parameters);
  }
  WarmStartsAtTheStart(input, fitted, logp, evals);

  FitResult result;
  auto total_cost = [&](const double* lp, bool* ok) {
    double cost = 0.0;
    *ok = true;
    for (auto& e : evals) {
      if (e->num_residuals() == 0) continue;
      VecX r(e->num_residuals());
      if (!e->Evaluate(lp, r.data(), nullptr, nullptr)) {
        *ok = false;
        return std::numeric_limits<double>::infinity();
      }
      cost += 0.5 * r.squaredNorm();
    }
    return cost;
  };

  if (options.global) {
    const Clock::time_point global_start = Clock::now();
    // DIRECT-L: a deterministic derivative-free global search over the log box; Ceres polishes.
    nlopt::opt opt(nlopt::GN_DIRECT_L, m);
    std::vector<double> lo(m), hi(m);
    for (int k = 0; k < m; ++k) SearchBox(input.parameters[fitted[k].input_index], &lo[k], &hi[k]);
    opt.set_lower_bounds(lo);
    opt.set_upper_bounds(hi);
    opt.set_maxeval(options.global_evaluations);
    struct Ctx {
      decltype(total_cost)* f;
      int evaluations;
      const FitOptions* options;
      Clock::time_point start;
      double best;
    } ctx{&total_cost, 0, &options, start, std::numeric_limits<double>::infinity()};
    opt.set_min_objective(
        [](const std::vector<double>& x, std::vector<double>&, void* data) {
          Ctx* c = static_cast<Ctx*>(data);
          ++c->evaluations;
          bool ok;
          const double v = (*c->f)(x.data(), &ok);
          if (ok) c->best = std::min(c->best, v);
          if (c->options->progress) {
            FitIterationInfo info;
            info.global = true;
            info.iteration = c->evaluations;
            info.budget = c->options->global_evaluations;
            info.cost = c->best;
            info.seconds = std::chrono::duration<double>(Clock::now() - c->start).count();
            c->options->progress(info);
          }
          return ok ? v : 1e30;  // a failed solve is a very bad point, not an error
        },
        &ctx);
    std::vector<double> x = logp;
    for (int k = 0; k < m; ++k) x[k] = std::min(hi[k], std::max(lo[k], x[k]));
    double best = 0.0;
    try {
      opt.optimize(x, best);
    } catch (const std::exception&) {
      // maxeval reached is reported as success by NLopt; anything else keeps the best so far.
    }
    result.global_evaluations = ctx.evaluations;
    if (best < 1e30) logp = x;
    result.global_seconds = std::chrono::duration<double>(Clock::now() - global_start).count();
  }

  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  problem.AddParameterBlock(logp.data(), m);
  for (int k = 0; k < m; ++k) {
    const FitParameter& p = input.parameters[fitted[k].input_index];
    if (p.min) problem.SetParameterLowerBound(logp.data(), k, std::log(*p.min));
    if (p.max) problem.SetParameterUpperBound(logp.data(), k, std::log(*p.max));
  }
  std::vector<const CaseEvaluator*> observed;
  for (auto& e : evals)
    if (e->num_residuals() > 0) observed.push_back(e.get());
  problem.AddResidualBlock(new AllCasesCost(observed, options.num_threads), nullptr, logp.data());

  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = 1;  // the cases run in parallel inside AllCasesCost, in a fixed order
  so.function_tolerance = 1e-12;
  so.parameter_tolerance = 1e-10;
  so.gradient_tolerance = 1e-14;
  so.logging_type = ceres::SILENT;
  ProgressCallback callback(options, start);
  so.callbacks.push_back(&callback);
  ceres::Solver::Summary summary;
  const double ceres_start = std::chrono::duration<double>(Clock::now() - start).count();
  ceres::Solve(so, &problem, &summary);
  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  for (const ceres::IterationSummary& it : summary.iterations) {
    result.cost_per_iteration.push_back(it.cost);
    result.seconds_per_iteration.push_back(ceres_start + it.cumulative_time_in_seconds);
  }
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.num_residuals = total_residuals;
  result.message = summary.message;
  result.success = summary.IsSolutionUsable() && summary.termination_type == ceres::CONVERGENCE;
  if (!summary.IsSolutionUsable() || !std::isfinite(summary.final_cost)) {
    result.success = false;
    result.message = "no usable solution: " + summary.message;
  } else if (summary.termination_type == ceres::NO_CONVERGENCE) {
    result.message = "did not converge within max_iterations: " + summary.message;
  }

  // Jacobian at the solution (log space, sigma-weighted, after the loss) for identifiability.
  Eigen::MatrixXd J;
  VecX r;
  {
    double cost = 0.0;
    ceres::CRSMatrix crs;
    std::vector<double> res;
    ceres::Problem::EvaluateOptions eo;
    const bool ok = problem.Evaluate(eo, &cost, &res, nullptr, &crs);
    if (!ok) {
      // The first case that failed (in case order, whatever thread ran it), and whether its data
      // or its solve failed: they call for different fixes.
      std::string why;
      bool data = false;
      for (const auto& e : evals) {
        bool is_data = false;
        const std::string failure = e->last_failure(&is_data);
        if (why.empty() && !failure.empty()) why = failure, data = is_data;
      }
      const std::string at = result.iterations <= 0 ? "start" : "fitted";
      result.success = false;
      if (data)
        result.message = "bad data: " + why + " at the " + at + " values";
      else
        result.message = "the forward solve fails at the " + at + " values" +
                         (why.empty() ? std::string() : " (" + why + ")") +
                         ": a solver limit, not bad data (start nearer, or raise "
                         "solver.max_iterations)";
    } else {
      J.setZero(crs.num_rows, crs.num_cols);
      for (int i = 0; i < crs.num_rows; ++i)
        for (int k = crs.rows[i]; k < crs.rows[i + 1]; ++k) J(i, crs.cols[k]) = crs.values[k];
      r = Eigen::Map<VecX>(res.data(), res.size());
    }
  }
  const int dof = std::max(1, effective_residuals - m);
  result.residual_dof = dof;
  result.residual_variance = 2.0 * result.final_cost / dof;
  // Trusted sigmas leave the covariance as the sigmas state it; the variance is still reported,
  // so that a model that does not explain the data is not passed silently.
  const double covariance_scale = options.trusted_sigmas ? 1.0 : result.residual_variance;

  // Identifiability: columns the residuals do not depend on, directions of J's null space, and
  // parameters whose log is determined only within max_log_std (identifiability.h, shared with
  // the motion fit). With full rank, Ceres' covariance of the parameter block.
  std::vector<std::string> fitted_names;
  for (const auto& f : fitted) fitted_names.push_back(f.name);
  const IdentifiabilityReport verdict = AssessIdentifiability(
      J, fitted_names, covariance_scale, options.max_log_std, [&](Eigen::MatrixXd* cov) {
        ceres::Covariance::Options co;
        co.algorithm_type = ceres::DENSE_SVD;
        co.num_threads = 1;
        ceres::Covariance covariance(co);
        std::vector<std::pair<const double*, const double*>> blocks = {{logp.data(), logp.data()}};
        cov->resize(m, m);
        if (!covariance.Compute(blocks, &problem) ||
            !covariance.GetCovarianceBlock(logp.data(), logp.data(), cov->data()))
          return false;
        cov->transposeInPlace();  // row-major from Ceres (symmetric anyway)
        return true;
      });
  const std::vector<bool>& identifiable = verdict.identifiable;
  const std::vector<std::string>& reason = verdict.reason;
  const Eigen::MatrixXd& cov_log = verdict.cov_log;
  result.correlation.setZero(m, m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j)
      result.correlation(i, j) = cov_log(i, j) / std::sqrt(cov_log(i, i) * cov_log(j, j));

  // Every parameter of the model, fitted or not.
  const Material final_material = MaterialAt(input, fitted, logp.data());
  for (size_t k = 0; k < input.parameters.size(); ++k) {
    const FitParameter& p = input.parameters[k];
    ParameterEstimate e;
    e.name = p.name;
    e.unit = ParameterUnit(p.name);
    e.value = p.value;
    e.start = p.value;
    e.fitted = p.fit;
    for (int f = 0; f < m; ++f) {
      if (fitted[f].input_index != static_cast<int>(k)) continue;
      e.value = std::exp(logp[f]);
      e.identifiable = identifiable[f];
      e.reason = reason[f];
      if (identifiable[f]) e.std = e.value * std::sqrt(cov_log(f, f));  // delta method
      e.at_bound = (p.min && std::abs(logp[f] - std::log(*p.min)) < 1e-6) ||
                   (p.max && std::abs(logp[f] - std::log(*p.max)) < 1e-6);
      result.fitted_names.push_back(p.name);
    }
    if (p.name == "bend_stiffness_2" && !p.fit && !input.material.bend_stiffness_2)
      e.value = final_material.B2();
    result.parameters.push_back(e);
  }

  // Shapes and RMS per observation at the fitted parameters.
  for (size_t c = 0; c < evals.size(); ++c) {
    Mat3X shape;
    // Without the robust loss, so that the reported misfit is in measurement units.
    // From the fit's own last state: the equilibrium the fit followed, not one a cold start
    // might find instead.
    CaseEvaluator plain(input, static_cast<int>(c), fitted, nullptr);
    if (const std::optional<RodState> warm = evals[c]->WarmState()) plain.SetWarmStart(*warm);
    VecX rr(std::max(1, plain.num_residuals()));
    RodState state;
    if (!plain.Evaluate(logp.data(), rr.data(), nullptr, &shape, &state)) continue;
    result.shapes.push_back(shape);
    const FitCase& fc = input.cases[c];
    // The poked section at the fit, for the report's measured-versus-fitted section plot.
    Eigen::Matrix3Xd rest_ring, ring;
    if (fc.load_case.poke && input.section) {
      try {
        const Material material = MaterialAt(input, fitted, logp.data());
        const RodModel model(input.rod, material, input.gravity, fc.load_case, input.springs);
        const PokeResult poke =
            SolvePoke(model, state, *input.section,
                      RingStiffness{material.ring_bend_stiffness, material.ring_stretch_stiffness});
        if (poke.ring.summary.converged) {
          rest_ring = poke.rest_world;
          ring = poke.deformed_world;
        }
      } catch (const std::invalid_argument&) {
        // No section to show; the residuals above already count this case.
      }
    }
    result.rest_sections.push_back(rest_ring);
    result.sections.push_back(ring);
    for (size_t o = 0; o < fc.observations.size(); ++o) {
      ObservationFit of;
      of.case_index = static_cast<int>(c);
      of.case_name = fc.load_case.name;
      of.label = o < fc.labels.size() ? fc.labels[o] : fc.observations[o]->type();
      of.type = fc.observations[o]->type();
      of.unit = of.type == "image_points" || of.type == "images" ? "px" : "m";
      of.num_measurements = fc.observations[o]->num_measurements();
      fc.observations[o]->RmsError(shape, &of.rms);
      result.observations.push_back(of);
    }
    // The case's residual vector: observations, then grasp forces, then surface points.
    int offset = 0;
    for (const auto& o : fc.observations) offset += o->num_residuals();
    // The force readings, one entry per observation (its consecutive readings): forces in N,
    // moments in N m apart.
    const int nf = static_cast<int>(fc.grasp_forces.size());
    for (int f = 0; f < nf;) {
      const ForceMeasurement& first = fc.grasp_forces[f];
      const std::string& name = first.observation.empty() ? first.label : first.observation;
      double force_sum = 0.0, moment_sum = 0.0;
      int count = 0, with_moment = 0;
      auto record = [&](const char* unit, int index, const Vec3& error, double sigma) {
        MeasurementResidual mr;
        mr.case_index = static_cast<int>(c);
        mr.case_name = fc.load_case.name;
        mr.observation = name;
        mr.unit = unit;
        mr.measurement = index;
        mr.error = error;
        mr.sigma = sigma;
        result.measurement_residuals.push_back(mr);
      };
      for (; f < nf; ++f) {
        const ForceMeasurement& m = fc.grasp_forces[f];
        if ((m.observation.empty() ? m.label : m.observation) != name || m.type != first.type) break;
        const Vec3 force_error = rr.segment<3>(offset) * m.sigma;
        force_sum += force_error.squaredNorm();
        record("N", count, force_error, m.sigma);
        if (m.moment) {
          const Vec3 moment_error = rr.segment<3>(offset + 3) * m.sigma_moment;
          moment_sum += moment_error.squaredNorm();
          record("N m", with_moment, moment_error, m.sigma_moment);
          ++with_moment;
        }
        offset += m.num_residuals();
        ++count;
      }
      ObservationFit of;
      of.case_index = static_cast<int>(c);
      of.case_name = fc.load_case.name;
      of.label = name;
      of.type = first.type;
      of.unit = "N";
      of.num_measurements = count;
      of.rms = std::sqrt(force_sum / count);
      if (with_moment > 0) of.rms_moment = std::sqrt(moment_sum / with_moment);
      result.observations.push_back(of);
    }
    for (const SurfacePoints& sp : fc.surface_points) {  // [m]: the distance to the ring
      const int np = static_cast<int>(sp.points.size());
      const double sum = (rr.segment(offset, 3 * np) * sp.sigma).squaredNorm();
      for (int k = 0; k < np; ++k) {
        MeasurementResidual mr;
        mr.case_index = static_cast<int>(c);
        mr.case_name = fc.load_case.name;
        mr.observation = sp.label;
        mr.unit = "m";
        mr.measurement = k;
        mr.error = rr.segment<3>(offset + 3 * k) * sp.sigma;
        mr.sigma = sp.sigma;
        result.measurement_residuals.push_back(mr);
      }
      offset += 3 * np;
      ObservationFit of;
      of.case_index = static_cast<int>(c);
      of.case_name = fc.load_case.name;
      of.label = sp.label;
      of.type = "surface_points";
      of.unit = "m";
      of.num_measurements = np;
      of.rms = std::sqrt(sum / np);
      result.observations.push_back(of);
    }
  }
  for (const auto& e : evals) {
    const CaseEvaluator::Timing t = e->timing();
    result.solve_seconds += t.solve;
    result.jacobian_seconds += t.jacobian;
    result.observation_seconds += t.observation;
    result.forward_solves += t.solves;
  }
  result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return result;
}

}  // namespace rodfit
