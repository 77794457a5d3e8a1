// The cross-section model of the tissue paper §4 (docs/model.md, "Cross-section"): the section of
// a tube-like tissue at the instrument's arc length is a closed curve C that deforms in its own
// plane. C is a closed polyline of N nodes X_k (section coordinates: x along the rod's d1, y
// along d2), at rest the regular N-gon inscribed in the circle of radius R, numbered
// counter-clockwise from d1. Potential energy (paper eqs. 10–11), Pi = U_bend + U_stretch - W:
//
//   U_bend    = sum_k kb l_k / 2 (kappa_k - kappa°_k)^2,   kappa_k = 2 tan(phi_k / 2) / l_k
//   U_stretch = sum_k ks L_k / 2 (|e_k| / L_k - 1)^2,     e_k = X_{k+1} - X_k
//   W         = F . (X_c - X°_c) - sum_k (l_k / L_C) F . (X_k - X°_k)
//
// phi_k is the signed turning angle at node k between e_{k-1} and e_k (the rod's tan form,
// 2 tan(phi/2) = 2 (a x b) / (|a||b| + a.b)), l_k the rest Voronoi length, L_k the rest edge
// length and L_C their sum. kappa°_k is the curvature of the rest polygon, not 1/R: the two differ
// by (pi/N)^2 / 2 relative, and 1/R would make the unloaded polygon pre-stressed. F is the
// instrument force projected into the section plane, applied at the contact node c (the node
// whose outward rest normal is most opposite to F: where the force pushes into the tissue), and
// the body force -F / L_C, lumped by Voronoi length, balances it exactly.
//
// Constraints. The mass centre sum_k l_k X_k / L_C stays at its rest position (paper: "the mass
// centre of the curve unchanged"); and the rigid in-plane rotation, which the paper leaves free,
// is removed by sum_k l_k (X°_k x (X_k - X°_k)) = 0 (no mean rotation about the centre). Both
// are linear, so the solver works on X = X° + Z q with Z an orthonormal basis of their null space
// and every iterate satisfies them exactly. A soft rotation spring was rejected: under a dead
// push load the rigid rotation is not a zero-energy mode but an unstable one
// (Pi(alpha) = -|F| R (1 - cos alpha) for a load aimed at a node), so a penalty must beat |F| R
// and still biases the shape; pinning one node's tangential position would work as well but
// singles out a node. For a load aimed at a node the exact solution is mirror symmetric and
// satisfies the rotation constraint by itself; otherwise the pin carries the moment
// (X_c - X_centre) x F (RingResult::pin_moment).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/model/frames.h"

namespace rodfit {

class RodModel;
struct RodState;

/// The `section:` block: geometry of the ring and of the mesh propagation (docs/formats.md,
/// `section`).
struct SectionSpec {
  double radius = 0.0;        ///< rest radius R of the curve C [m]
  int nodes = 32;             ///< N, nodes of C (>= 8)
  double h_factor = 0.5;      ///< h = h_factor sqrt(A): reach of the mesh propagation (eq. 12)
  double stop_factor = 0.01;  ///< propagation stops below stop_factor sqrt(A) [-]

  double area() const;                  ///< A = pi R^2 [m^2]
  double influence_length() const;      ///< h [m]
  double stop_threshold() const;        ///< [m]
  bool Check(std::string* why) const;
};

/// Stiffness of the ring (docs/model.md, "Cross-section": `ring_bend_stiffness`,
/// `ring_stretch_stiffness`).
struct RingStiffness {
  double bend = 0.0;     ///< kb [N m^2]
  double stretch = 0.0;  ///< ks [N]
  bool Check(std::string* why) const;
};

/// Rest constants of the ring, built once from a SectionSpec.
struct RingGeometry {
  int n = 0;                   ///< nodes
  double radius = 0.0;         ///< [m]
  Eigen::Matrix2Xd rest;       ///< X°_k, section coordinates [m]
  std::vector<double> edge;    ///< L_k = |X°_{k+1} - X°_k| [m]
  std::vector<double> voronoi; ///< l_k = (L_{k-1} + L_k) / 2 [m]
  std::vector<double> rest_curvature;  ///< kappa°_k [1/m]
  double length = 0.0;         ///< L_C [m]
  /// Soft-norm length [m] guarding |e| = 0 and the full fold; 1e-9 of an edge, so delta^2 is below
  /// double round-off against |e|^2 and the energy is unchanged where it is regular.
  double guard = 0.0;

  int next(int k) const { return k + 1 == n ? 0 : k + 1; }
  int prev(int k) const { return k == 0 ? n - 1 : k - 1; }
};

/// Throws std::invalid_argument when spec.Check fails.
RingGeometry MakeRingGeometry(const SectionSpec& spec);

/// Node k's two coordinates in the packed vector x (size 2N): [x_0, y_0, x_1, y_1, ...].
inline int NodeDof(int k) { return 2 * k; }

/// Elastic energy U_bend + U_stretch [J] at the packed node displacements u = x - x° (2N
/// entries), for double and ceres::Jet (also nested). Displacements, not positions, are the
/// variables: the strain is formed as (|e|^2 - L^2) / (L (|e| + L)) with
/// |e|^2 - L^2 = 2 e°.du + du.du, so it keeps its relative precision however small it is (from
/// positions it would carry an absolute error of eps, i.e. stretch forces of eps ks, which a
/// stiff ring (ks R^2 / kb >> 1) turns into displacement noise eps ks R^3 / kb). Singular
/// points (coincident nodes, a full fold) are softened by geometry.guard so that values and
/// derivatives stay finite.
template <typename T>
T RingElasticEnergy(const RingGeometry& g, const RingStiffness& k, const T* u) {
  using std::sqrt;
  const T d2 = Cst<T>(g.guard * g.guard);
  T energy = Cst<T>(0.0);
  // Edge vector k from node k to k + 1 at rest, and its change.
  auto rest_edge = [&](int i, int c) { return g.rest(c, g.next(i)) - g.rest(c, i); };
  auto edge_change = [&](int i, int c) { return u[NodeDof(g.next(i)) + c] - u[NodeDof(i) + c]; };
  for (int i = 0; i < g.n; ++i) {
    const int h = g.prev(i);
    const double e0x = rest_edge(i, 0), e0y = rest_edge(i, 1);
    const double a0x = rest_edge(h, 0), a0y = rest_edge(h, 1);
    const T dex = edge_change(i, 0), dey = edge_change(i, 1);
    const T ex = Cst<T>(e0x) + dex, ey = Cst<T>(e0y) + dey;
    const T ax = Cst<T>(a0x) + edge_change(h, 0), ay = Cst<T>(a0y) + edge_change(h, 1);
    const double L0sq = e0x * e0x + e0y * e0y;
    const T len_e = sqrt(ex * ex + ey * ey + d2);
    const T len_a = sqrt(ax * ax + ay * ay + d2);
    // Stretch of edge i (from node i to i + 1): |e| / L - 1, without cancellation.
    // The soft norm only enters the denominator, so the rest state has exactly zero strain.
    const T strain = (Cst<T>(2.0 * e0x) * dex + Cst<T>(2.0 * e0y) * dey + dex * dex + dey * dey) /
                     (Cst<T>(std::sqrt(L0sq)) * (len_e + Cst<T>(std::sqrt(L0sq))));
    energy += Cst<T>(0.5 * k.stretch * g.edge[i]) * strain * strain;
    // Bending at node i between a = e_{i-1} and e = e_i: 2 tan(phi/2) = 2 (a x e)/(|a||e| + a.e);
    // the denominator is > 0 with the soft norms, also at a full fold.
    const T tan_half = (ax * ey - ay * ex) / (len_a * len_e + ax * ex + ay * ey);
    const T dk = Cst<T>(2.0 / g.voronoi[i]) * tan_half - Cst<T>(g.rest_curvature[i]);
    energy += Cst<T>(0.5 * k.bend * g.voronoi[i]) * dk * dk;
  }
  return energy;
}

/// The same energy with its closed-form gradient (2N) and Hessian (2N x 2N) with respect to u
/// (= with respect to the positions), either optional. Derivatives use the exact (unguarded)
/// formulas: identical to the guarded energy's to round-off wherever nodes do not coincide.
double RingElasticEnergy(const RingGeometry& g, const RingStiffness& k, const Eigen::VectorXd& u,
                         Eigen::VectorXd* gradient = nullptr, Eigen::MatrixXd* hessian = nullptr);

/// The dead load of eq. 11 as nodal forces f (2N): F at the contact node minus F l_k / L_C at
/// every node; sums to zero. W = f . u.
struct RingLoad {
  int contact_node = -1;             ///< -1 for a zero force
  Eigen::Vector2d force = Eigen::Vector2d::Zero();  ///< F in section coordinates [N]
  Eigen::VectorXd nodal;             ///< f [N], size 2N
  /// d f / d F (2N x 2): the load's dependence on F at a fixed contact node.
  Eigen::Matrix<double, Eigen::Dynamic, 2> d_nodal_d_force;
};

/// Contact node: argmin_k n°_k . F (n°_k the outward rest normal); the lower index on a tie.
int ContactNode(const RingGeometry& g, const Eigen::Vector2d& force);
RingLoad MakeRingLoad(const RingGeometry& g, const Eigen::Vector2d& force);
/// The same into *load, whose vectors keep their storage once sized (the runtime's mesh).
void MakeRingLoad(const RingGeometry& g, const Eigen::Vector2d& force, RingLoad* load);

/// The two linear constraints' rows (3 x 2N): mass centre (x, y) and mean rotation, each row
/// normalised; C u = 0.
Eigen::Matrix<double, 3, Eigen::Dynamic> RingConstraints(const RingGeometry& g);

/// Mass centre sum_k l_k X_k / L_C of the nodes (2 x N) [m].
Eigen::Vector2d RingCentre(const RingGeometry& g, const Eigen::Matrix2Xd& nodes);

enum class RingTermination {
  kZeroLoad,          ///< F = 0: the rest ring, nothing solved (also with a warm start)
  kGradientTolerance,
  kStepTolerance,
  kRoundOff,          ///< the Newton step promises less than Pi's round-off
  kMaxIterations,
  kLineSearchFailed,
  kNotFinite,
};
const char* ToString(RingTermination t);

struct RingSummary {
  bool converged = false;
  RingTermination reason = RingTermination::kMaxIterations;
  int iterations = 0;
  double gradient_norm = 0.0;   ///< infinity norm of the constrained gradient [N]
  double energy = 0.0;          ///< Pi at the result [J]
  int hessian_shifts = 0;       ///< iterations whose reduced Hessian needed a diagonal shift
  /// Whether the reduced Hessian at the result is positive definite (a stable equilibrium); the
  /// sensitivities are only computed then.
  bool stable = false;
  bool IsUsable() const { return converged; }
  std::string BriefReport() const;
};

struct RingResult {
  Eigen::Matrix2Xd rest;         ///< X°_k [m], section coordinates
  Eigen::Matrix2Xd nodes;        ///< X_k at equilibrium [m]
  int contact_node = -1;
  Eigen::Vector2d force = Eigen::Vector2d::Zero();  ///< F in the section [N]
  /// Moment [N m] of the loads about the mass centre, (X_c - centre) x F, which the rotation
  /// constraint carries; zero for a load aimed at the contact node's normal.
  double pin_moment = 0.0;
  RingSummary summary;
  /// Exact sensitivities at equilibrium, d x / d p = -Z (Z^T H Z)^-1 Z^T d grad / d p, packed
  /// like x (2N); empty unless requested and the equilibrium is stable.
  Eigen::VectorXd d_nodes_d_log_bend;     ///< [m]
  Eigen::VectorXd d_nodes_d_log_stretch;  ///< [m]
  Eigen::Matrix<double, Eigen::Dynamic, 2> d_nodes_d_force;  ///< [m/N], at a fixed contact node

  Eigen::Matrix2Xd displacement() const { return nodes - rest; }
};

/// Where the section sits in the world: centre and the material directors spanning its plane.
struct SectionPlacement {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< [m]
  Eigen::Vector3d d1 = Eigen::Vector3d::UnitX();     ///< section x axis (unit)
  Eigen::Vector3d d2 = Eigen::Vector3d::UnitY();     ///< section y axis (unit, perpendicular)
  Eigen::Vector3d normal() const { return d1.cross(d2); }  ///< d3, the plane's normal
};

/// The section at rest arc length s of a rod state: centre interpolated linearly between the
/// vertices of the edge j containing s, plane spanned by that edge's material directors
/// (RodModel::MaterialFrame). Throws std::invalid_argument for s outside [0, L].
SectionPlacement SectionAt(const RodModel& model, const RodState& state, double s);

/// F projected into the section plane, in section coordinates (F . d1, F . d2) [N].
Eigen::Vector2d ProjectToSection(const Eigen::Vector3d& force_world, const SectionPlacement& p);

/// Section coordinates to world points: centre + x d1 + y d2 (column per node) [m].
Eigen::Matrix3Xd SectionToWorld(const Eigen::Matrix2Xd& points, const SectionPlacement& p);

}  // namespace rodfit
