// The statics of the cross-section ring (docs/model.md, "Cross-section"; tissue paper §4
// eqs. 10–11): the constrained Newton solve of the ring's energy (model/cross_section.h) under an
// in-plane force, with its stiffness and force sensitivities.
#pragma once

#include <memory>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "rodfit/model/cross_section.h"

namespace rodfit {

struct RingSolveOptions {
  int max_iterations = 50;            ///< Newton iterations before giving up
  int max_line_search_steps = 40;     ///< step halvings per iteration
  /// Converged when the constrained gradient's infinity norm is below this times |F| [-].
  double gradient_tolerance = 1e-10;
  /// ... or when the Newton step changes no displacement by more than this times the largest
  /// displacement (the step is then taken) [-]: the gradient's round-off floor (about eps ks |u|
  /// / L_k from the stretch, more from cancellation in the turning angle of a fine ring) can
  /// exceed gradient_tolerance |F|. A step promising less than Pi's round-off also ends the solve.
  double step_tolerance = 1e-10;
  bool compute_sensitivities = true;  ///< fill the d_nodes_d_* fields of RingResult
  bool Check(std::string* why) const;
};

/// The ring's solve with its constants (geometry, the constraints' null-space basis) built once
/// and every buffer kept between solves: after a first solve into a RingResult, later solves
/// into the same result allocate no heap memory unless options.compute_sensitivities is set
/// (the interactive runtime re-solves the ring of a poke at every mesh update). Throws
/// std::invalid_argument for an invalid spec, stiffness or options.
class NewtonMinimizer;

class RingSolver {
 public:
  RingSolver(const SectionSpec& spec, const RingStiffness& stiffness,
             const RingSolveOptions& options = {});
  ~RingSolver();
  /// SolveRing's solve (below) into *result. Throws std::invalid_argument for a non-finite
  /// force or a warm start without one column per node.
  void Solve(const Eigen::Vector2d& force_in_plane, const Eigen::Matrix2Xd* warm_start,
             RingResult* result);
  const RingGeometry& geometry() const { return g_; }

 private:
  // The null-space basis Z is the last 2N - 3 columns of Q = H_0 H_1 H_2 (the Householder
  // reflections H_k = I - tau_k v_k v_k^T of C^T = QR). Applying the three reflections costs
  // O(N^2) where the dense products with Z cost O(N^3): Z^T H Z is most of a ring iteration.
  void ToReduced(const Eigen::VectorXd& x, Eigen::VectorXd* reduced);       // Z^T x
  void FromReduced(const Eigen::VectorXd& reduced, Eigen::VectorXd* x);     // Z y
  void ReducedHessian(const Eigen::MatrixXd& hessian, Eigen::MatrixXd* reduced);  // Z^T H Z
  double Potential(const Eigen::VectorXd& u, Eigen::VectorXd* grad, Eigen::MatrixXd* hess,
                   double* scale);
  void Sensitivities(const Eigen::VectorXd& u, RingResult* result);

  RingGeometry g_;
  RingStiffness stiffness_;
  RingSolveOptions options_;
  Eigen::MatrixXd reflectors_;  // column k: v_k (2N)
  Eigen::Vector3d tau_ = Eigen::Vector3d::Zero();
  Eigen::MatrixXd Z_;           // explicit, for the sensitivities only
  RingLoad load_;
  Eigen::VectorXd u_, grad_, grad_try_, gr_, p_, du_, u_try_, full_;
  Eigen::MatrixXd hess_, work_, hr_;
  Eigen::LLT<Eigen::MatrixXd> llt_;  // the reduced Hessian's at the result (stability, sensitivities)
  class Problem;                     // the solve as a Newton problem (ring.cc)
  std::unique_ptr<Problem> problem_;
  std::unique_ptr<NewtonMinimizer> minimizer_;
};

/// Statics of the ring under the in-plane force F (section coordinates [N]): Newton on the
/// constrained coordinates with a dense Cholesky (N is small), a diagonal shift when the
/// reduced Hessian is indefinite, Armijo backtracking on Pi and an iteration cap. `warm_start`
/// (node positions, 2 x N, section coordinates) is projected onto the constraints first. Throws
/// std::invalid_argument for an invalid spec, stiffness or options.
RingResult SolveRing(const SectionSpec& spec, const RingStiffness& stiffness,
                     const Eigen::Vector2d& force_in_plane, const RingSolveOptions& options = {},
                     const Eigen::Matrix2Xd* warm_start = nullptr);

}  // namespace rodfit
