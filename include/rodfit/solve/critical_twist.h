// The critical twist of a rod held by two clamps (docs/solvers.md, "Critical twist"): from the
// case's untwisted equilibrium, the clamp at s = 0 is rolled about its own tangent, its frame
// R_A(roll) = R_A Rot_d3(roll) (a positive roll turns d1 towards d2), the roll an unwrapped
// continuation parameter, and the equilibrium is followed until it first loses stability: the
// smallest eigenvalue of the Hessian on the free dofs (held rows excluded) crosses zero, at a
// bifurcation (the branch goes on through it: Greenhill's straight rod) or at a fold (the branch
// turns back in the roll: the heavy loop). The crossing is located to round-off, and the
// critical roll is differentiated by the material parameters and the clamp angles from the
// conditions that hold there (the null vector of the Hessian).
//
// Every equilibrium is found by the one Newton minimizer: the continuation's steps by
// SolveStatics, the pseudo-arclength corrector through the crossing as a Newton problem of its
// own on the same minimizer.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/model/rod.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

/// How the equilibrium first loses stability as the clamp rolls.
enum class TwistInstability {
  kBifurcation,  ///< an eigenvalue crosses zero while the branch goes on in the roll
  kFold,         ///< the branch turns back in the roll (the roll is at a maximum)
  kNoneInRange,  ///< stable up to CriticalTwistOptions::max_roll_rad
};

const char* TwistInstabilityName(TwistInstability kind);

struct CriticalTwistOptions {
  /// [rad] the search range: the roll goes from 0 to this (negative: the other way).
  double max_roll_rad = 8.0 * 3.14159265358979323846;
  /// [rad] natural-parameter steps of the roll: the first, the largest, and the smallest before
  /// the crossing is taken over by the pseudo-arclength continuation.
  double initial_step_rad = 0.1;
  double max_step_rad = 1.0;
  double min_step_rad = 1e-3;
  /// Steps in all (natural and pseudo-arclength) before giving up.
  int max_steps = 2000;
  /// [rad] the crossing is located on the arclength until a step is below this (it bounds the
  /// roll's error; a fold's roll is flat there, so its error is far smaller).
  double locate_tolerance_rad = 1e-10;
  int max_locate_iterations = 100;
  /// The solves of the natural steps. escape_saddles is ignored (a saddle is reported, not
  /// left) and load continuation is not used (a failed step is retried shorter instead).
  StaticsOptions statics = DefaultStatics();
  bool Check(std::string* why) const;

  static StaticsOptions DefaultStatics() {
    StaticsOptions s;
    s.max_iterations = 20;
    s.escape_saddles = false;
    return s;
  }
};

/// One accepted point of the path.
struct CriticalTwistPathPoint {
  double roll_rad = 0.0;
  /// [N/m^2] smallest eigenvalue of H v = lambda M v on the free dofs (see CriticalTwistResult).
  double lambda_min = 0.0;
  double clamp_torque_Nm = 0.0;  ///< dPi/droll: the torque that holds the roll [N m]
  bool arclength = false;        ///< a pseudo-arclength point (else a natural step)
};

struct CriticalTwistResult {
  /// False: no answer (the message says why). True: `kind` is the outcome.
  bool ok = false;
  TwistInstability kind = TwistInstability::kNoneInRange;
  /// [rad] the located critical roll; kNoneInRange: the last roll reached (the range's end).
  double critical_roll_rad = std::numeric_limits<double>::quiet_NaN();
  /// [rad] the roll's change in the last locating step (a bound on the roll's error).
  double bracket_rad = std::numeric_limits<double>::quiet_NaN();
  /// [N/m^2] the smallest eigenvalue there (~0 at a crossing; positive for kNoneInRange), of
  /// H v = lambda M v with H the Hessian on the free dofs and M the lumped length metric
  /// (Voronoi length per position, edge length cubed per twist angle), so that it converges with
  /// the segments; lambda_unit = min(B1, B2, GJ) / L^4 gives its scale.
  double lambda_min = std::numeric_limits<double>::quiet_NaN();
  double lambda_unit = std::numeric_limits<double>::quiet_NaN();
  /// Eigenvalues within round-off of lambda_min (2: a rod symmetric about its axis).
  int multiplicity = 1;
  double clamp_torque_Nm = std::numeric_limits<double>::quiet_NaN();  ///< dPi/droll there
  /// The equilibrium at critical_roll_rad (its clamp frame rolled), and the critical mode: the
  /// eigenvector of lambda_min over the free dofs (RodModel::VertexDof / TwistDof), v^T M v = 1.
  RodState state;
  Eigen::VectorXd mode;
  std::vector<CriticalTwistPathPoint> path;
  // Counters.
  int natural_steps = 0;      ///< accepted natural-parameter steps
  int failed_steps = 0;       ///< natural steps retried shorter (no solve, unstable, a jump)
  int arclength_steps = 0;    ///< accepted pseudo-arclength steps
  int corrector_solves = 0;   ///< pseudo-arclength corrector solves (steps and locating)
  int locate_iterations = 0;
  int newton_iterations = 0;  ///< of every solve
  int eigen_iterations = 0;   ///< subspace inverse iterations
  double seconds = 0.0;
  std::string message;
  std::string BriefReport() const;
};

/// The critical roll of `model`'s clamp at s = 0, from `untwisted`, an equilibrium of `model`
/// (its clamp frame the model's; it is re-solved first). The model needs an end clamp that holds
/// the frame (end_clamp with a normal); no moment loads, no symmetry plane. The untwisted
/// equilibrium must be strictly stable (a neutral mode, such as a weightless loop turning about
/// coaxial clamps, is refused: there is no branch to follow). Never throws for a failed
/// continuation: the result says why.
CriticalTwistResult CriticalTwist(const RodModel& model, const RodState& untwisted,
                                  const CriticalTwistOptions& options = CriticalTwistOptions());

/// A parameter the critical roll is differentiated by.
struct CriticalTwistParameter {
  enum class Kind {
    kStiffness,        ///< d/dlog p of a stiffness scaling the terms it drives (below)
    kSpring,           ///< d/dlog K of the springs of zones with parameter `spring` ("": K)
    kLinearDensity,    ///< d/dlog rho: the rod's weight (gravity's vertex loads)
    kClampRotation,    ///< d/dphi [1/rad]: clamp A's frame turned about world `axis` at x_0
    kEndClampRotation  ///< d/dphi [1/rad]: the end clamp's frame turned about `axis` at x_n
  };
  Kind kind = Kind::kStiffness;
  /// kStiffness: the stiffnesses it scales together (bend_stiffness with bend_stiffness_2 tied:
  /// bend1 and bend2).
  bool bend1 = false, bend2 = false, twist = false, stretch = false;
  std::string spring;
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();  ///< unit, world frame

  static CriticalTwistParameter Stiffness(bool b1, bool b2, bool gj, bool ea) {
    CriticalTwistParameter p;
    p.bend1 = b1, p.bend2 = b2, p.twist = gj, p.stretch = ea;
    return p;
  }
  static CriticalTwistParameter LinearDensity() {
    CriticalTwistParameter p;
    p.kind = Kind::kLinearDensity;
    return p;
  }
  static CriticalTwistParameter Rotation(bool end_clamp, const Eigen::Vector3d& axis) {
    CriticalTwistParameter p;
    p.kind = end_clamp ? Kind::kEndClampRotation : Kind::kClampRotation;
    p.axis = axis;
    return p;
  }
};

/// d critical_roll / d p for each parameter at a located crossing (result.ok, kind not
/// kNoneInRange), model the one CriticalTwist was given. A fold: from the null vector v,
/// -(v . dg/dp) / (v . dg/droll) (g the gradient of Pi). A bifurcation: from the zero
/// eigenvalue along the path, -(dlambda/dp) / (dlambda/droll), the eigenvalue's derivatives
/// v^T (dH) v with dH the Hessian's change along the path's tangent (the parameter's own term
/// exactly, the state's and clamps' motion by fourth-order differences of the assembly). A
/// parameter that splits a double critical eigenvalue has one-sided derivatives only: false
/// then, with the reason. False with the reason for a result without a crossing.
bool CriticalTwistDerivatives(const RodModel& model, const CriticalTwistResult& result,
                              const std::vector<CriticalTwistParameter>& parameters,
                              Eigen::VectorXd* d_roll, std::string* why);

}  // namespace rodfit
