// The discrete Cosserat rod (Bergou et al. 2008/2010; tissue paper eqs. 6–8; docs/model.md):
// n edges, vertices x_0..x_n, one twist angle per edge, reference frames transported in time.
//
// The clamp at s = 0 is a fixed ghost edge along the clamp tangent carrying the clamp frame.
// Vertex 0 is treated as a bending vertex between the ghost edge and edge 0 with half a Voronoi
// cell (l_0 / 2): the turning from the clamp tangent (at s = 0) to edge 0 (at s = l_0 / 2) is
// the odd reflection of the angle about the clamp, which keeps the scheme second order and
// makes an end moment close a circle. A clamp at s = L is the mirror image: a ghost edge after
// vertex n carrying the end clamp's frame, vertex n a bending vertex with half a cell; its twist
// angle is a degree of freedom when the end may turn about its tangent.
//
// Held points (an end clamp's or end pin's vertex n, interior pins, a grasp) are vertices whose
// position is held where the state puts them; the model moves the vertex nearest to each held
// arc length onto it, so the held point is the material point at that s. The solver moves the
// held values from where a start state has them to the model's targets by continuation.
//
// Free degrees of freedom, in blocks j = [x_{j+1} (3), theta_j (1)], j = 0..n-1, and with an end
// clamp one more block [ghost vertex (held), ghost twist]. Held vertices keep their dofs with
// Dirichlet rows, so the band structure is the same for every scene.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/model/scene.h"

namespace rodfit {

using Mat3X = Eigen::Matrix3Xd;
using VecX = Eigen::VectorXd;

/// The configuration of a rod: vertices, twist angles, the time-transported reference frame and
/// the frames held at the ends. The edge vectors `e` are the primary record of the shape (the
/// stretch energy reads them: strains computed from differences of vertex coordinates would
/// carry a round-off of eps |x| / l, which against a stiff EA swamps the loads); `x` is kept equal
/// to x_0 + the summed edges. Code that edits `x` directly calls SyncEdges().
struct RodState {
  Mat3X x;          ///< vertices x_0..x_n [m], column i
  Mat3X e;          ///< edges e_j = x_{j+1} - x_j [m], column j
  VecX theta;       ///< twist angle of edge j against its reference frame [rad], size n
  Mat3X ref_u;      ///< reference director u_j of edge j (unit, perpendicular to ref_t_j)
  Mat3X ref_t;      ///< tangent at which ref_u_j was last transported
  VecX ref_twist;   ///< reference twist at vertex i = 0..n [rad] (n: with an end clamp only)
  Vec3 clamp_t = Vec3::UnitX();   ///< unit d3 of the clamp at s = 0 (the ghost edge's tangent)
  Vec3 clamp_d1 = Vec3::UnitZ();  ///< unit d1 of the clamp at s = 0
  Vec3 end_t = Vec3::Zero();      ///< end clamp's ghost: unit tangent (zero without end clamp)
  Vec3 end_u = Vec3::Zero();      ///< end clamp's ghost: reference director
  double end_theta = 0.0;         ///< end clamp's ghost: twist angle about end_t from end_u
  /// A symmetric half's mirror plane: a point of it [m] (its normal is end_t). Moved from the
  /// start state's own plane to the case's by continuation, like a held point.
  Vec3 plane_point = Vec3::Zero();

  int num_edges() const { return static_cast<int>(theta.size()); }
  Vec3 vertex(int i) const { return x.col(i); }
  /// Recomputes e from x (after x was edited directly).
  void SyncEdges();
  /// Recomputes x from x_0 and e.
  void SyncVertices();
};

/// Material frame of one edge: d3 the tangent, d1 and d2 the material directors.
struct EdgeFrame {
  Vec3 d1, d2, d3;
};

/// A vertex held in position (all three directions, or only along `normal` for a symmetry
/// plane's middle vertex).
struct HeldVertex {
  enum class Kind { kEndClamp, kEndPin, kPin, kGrasp };
  Kind kind = Kind::kPin;
  int vertex = 0;
  double s = 0.0;                   ///< [m] the held arc length (the vertex's)
  Vec3 target = Vec3::Zero();       ///< [m] where the case holds it
  int index = 0;                    ///< which pin (kPin)
  std::string Label() const;        ///< "end_clamp", "end_pin", "pins[2]", "grasp"
};

/// A moment applied to one edge's rigid rotation: dead (fixed in space) or follower
/// (components in the edge's d1, d2, d3). Its work is not a potential in 3-D, so it enters the
/// equilibrium as a generalised force with its own (non-symmetric) load stiffness.
struct EdgeMoment {
  int edge = 0;
  Vec3 moment = Vec3::Zero();  ///< [N m] world (dead) or material components (follower)
  bool follower = false;
};

/// Why a case's `symmetry` plane cannot be used (empty when it can, or when the case declares
/// none): the whole case must be its own mirror image, held by a clamp and its mirror-image
/// end_clamp under gravity in the plane, with an odd number of even segments.
std::string SymmetryProblem(const RodSpec& rod, const Vec3& gravity, const LoadCase& load_case,
                            bool has_springs);

/// Constants of one load case on one rod: geometry, stiffness, loads (the Pinocchio "Model").
/// Built once per case; the solver's scratch lives elsewhere.
class RodModel {
 public:
  /// Throws std::invalid_argument with the reason when the inputs are not a valid rod
  /// (fewer than 2 segments, non-positive length or stiffness, clamp normal parallel to tangent,
  /// non-finite or unrepresentable values, held points that cannot be reached, ...).
  /// `springs`: the scene's attachment zones (none: no spring term is built).
  RodModel(const RodSpec& rod, const Material& material, const Vec3& gravity,
           const LoadCase& load_case, const std::vector<SpringZone>& springs = {});

  int num_edges() const { return n_; }
  int num_vertices() const { return n_ + 1; }
  /// 4 per edge, and a block of 4 more for the end's ghost edge (an end clamp, or a symmetric
  /// case's edge crossing its plane).
  int num_free_dofs() const { return 4 * n_ + (has_end_ghost() ? 4 : 0); }

  double length() const { return length_; }
  double rest_edge_length(int j) const { return rest_edge_[j]; }
  double min_rest_edge_length() const { return min_edge_; }
  /// Rest Voronoi length of the bending vertex i (0..n-1, and n with an end clamp) [m]; the
  /// end vertices have half a cell.
  double voronoi_length(int i) const { return voronoi_[i]; }
  /// The intrinsic curvature (k1°, k2°, tau°) [1/m] at bending vertex i: RodSpec::rest_curvature
  /// plus the profile's value at the vertex's arc length.
  const Vec3& rest_curvature(int i) const { return rest_curvature_[i]; }
  /// Whether any vertex has a rest curvature (the rod is not straight at rest).
  bool curved_at_rest() const { return curved_; }
  /// Arc length of vertex i in the rest state [m].
  double arc_length(int i) const { return arc_[i]; }
  const std::vector<double>& arc_lengths() const { return arc_; }

  const RodSpec& rod() const { return rod_; }
  const Material& material() const { return material_; }
  const LoadCase& load_case() const { return case_; }
  const Vec3& gravity() const { return gravity_; }

  const Vec3& clamp_position() const { return clamp_p_; }
  const Vec3& clamp_tangent() const { return clamp_d3_; }   ///< unit d3 at s = 0
  const Vec3& clamp_d1() const { return clamp_d1_; }        ///< unit d1 at s = 0

  // The clamp at s = L (end_clamp), or a symmetric case's plane: a ghost edge after vertex n.
  bool has_end_clamp() const { return end_clamp_; }
  bool has_end_ghost() const { return end_clamp_ || symmetric_; }
  /// True when the end clamp holds d1 too (a normal was given): the ghost's twist is held.
  bool end_twist_held() const { return end_twist_held_; }
  const Vec3& end_tangent() const { return end_d3_; }   ///< unit d3 of the ghost
  const Vec3& end_d1() const { return end_d1_; }        ///< unit d1 at s = L (when held)
  /// The ghost edge's rest length: the last edge's for an end clamp (the ghost never stretches),
  /// the crossing edge's for a symmetric half.
  double end_ghost_length() const { return symmetric_ ? crossing_length_ : rest_edge_[n_ - 1]; }

  // Symmetry (LoadCase::symmetry): this model is the half of the case's rod from the clamp to
  // the mirror plane. The full rod has 2n + 1 edges; its middle edge crosses the plane at a
  // right angle, and the half holds the vertex before it, the bending and twist there (a full
  // Voronoi cell, against the crossing edge as its ghost, free to twist) and half the crossing
  // edge's stretch. Its equilibrium is the full rod's mirror-symmetric one.
  bool symmetric() const { return symmetric_; }
  const Vec3& symmetry_point() const { return sym_point_; }
  const Vec3& symmetry_normal() const { return sym_normal_; }  ///< unit, from the half to the plane
  double crossing_length() const { return crossing_length_; }  ///< rest length of the middle edge
  int full_segments() const { return symmetric_ ? 2 * n_ + 1 : n_; }
  /// The mirror image of a point.
  Vec3 Mirror(const Vec3& p) const {
    return p - 2.0 * (p - sym_point_).dot(sym_normal_) * sym_normal_;
  }

  /// Lumped weight of vertex i: mass times gravity [N] (zero for a massless rod).
  Vec3 vertex_weight(int i) const { return vertex_mass_[i] * gravity_; }
  double vertex_mass(int i) const { return vertex_mass_[i]; }

  /// Dead external forces lumped on vertices (tip force, point forces, weights) [N].
  const Mat3X& vertex_forces() const { return vertex_forces_; }
  /// Moments on edges (tip moment, follower moment, point moments).
  const std::vector<EdgeMoment>& edge_moments() const { return edge_moments_; }
  /// True when the case carries moments: the equilibrium is then not the minimum of a
  /// potential and the solver uses the non-symmetric tangent.
  bool nonconservative() const { return !edge_moments_.empty(); }

  /// The case's load scale [N]: the largest of its weight, tip, point and poke forces, moments
  /// over L, and the elastic forces its held points and rest curvature impose (B / L^2 scaled
  /// by the imposed displacement or curvature). Not EA or GJ: a loaded rod must never pass for
  /// converged because its stretch stiffness is large. Solver tolerances are relative to it.
  double force_scale() const { return force_scale_; }

  /// The straight rod along the clamp tangent with the clamp frame, untwisted. Held points are
  /// where the straight rod has them; the solver moves them to their targets by continuation.
  RodState StraightState() const;
  /// The unloaded rest shape: the zero-energy configuration of the discrete rod with its rest
  /// curvature, from the clamp (straight when the rest curvature is zero).
  RodState RestState() const;
  /// The state for an ordered centre-line: points resampled to the vertices' arc lengths
  /// (given `s`, or the chord lengths scaled to L), edges laid at their rest lengths along the
  /// resampled directions from the clamp, the first edge turned onto the clamp tangent by the
  /// smallest rotation of the whole shape. Throws std::invalid_argument for fewer than two
  /// points, repeated points or s not increasing.
  RodState StateFromCentreline(const std::vector<double>& s, const Mat3X& points) const;
  /// Fills in the reference frames, twists and end frames of a state whose x (and e) are set:
  /// reference directors transported along the rod from the clamp, untwisted; an end clamp's
  /// ghost frame continuing the last edge's.
  void InitialiseFrames(RodState* state) const;

  // Springs (tissue paper: K(s) |r - r°|^2; cut stretches have K = 0).
  bool has_springs() const { return !zones_.empty(); }
  int num_spring_zones() const { return static_cast<int>(zones_.size()); }
  const SpringZone& spring_zone(int z) const { return zones_[z]; }
  /// Stiffness of zone z [N/m^2] from the material.
  double zone_stiffness(int z) const;
  /// Length [m] of vertex i's cell that zone z covers and no cut removes: the spring of vertex
  /// i in zone z has stiffness zone_stiffness(z) * zone_cell_length(z, i) [N/m].
  double zone_cell_length(int z, int i) const { return zone_length_[z][i]; }
  /// Rest position of vertex i, where its springs pull it (the rest shape, RestState()).
  Vec3 spring_anchor(int i) const { return anchor_.col(i); }

  // Held points.
  const std::vector<HeldVertex>& held() const { return held_; }
  /// Consecutive held points (the clamp first) farther apart than (1 + strain) times the rod
  /// between them: one line each, naming both, their distance and the rod between them. Not an
  /// error (a taut wire does stretch), but a rod length or held position given wrong is the
  /// likelier cause of more than a percent, and it biases a fit.
  std::vector<std::string> StretchedSpans(double strain) const;
  /// Index into held() of the point holding vertex i, or -1.
  int held_at_vertex(int i) const { return held_of_vertex_[i]; }
  /// Per free dof: held (a held vertex's coordinate, an end ghost's vertex, a held ghost twist).
  const std::vector<char>& held_dofs() const { return held_dofs_; }
  /// Grasp: the grasped vertex (-1 without a grasp) and its target.
  int grasp_vertex() const { return grasp_vertex_; }
  const Vec3& grasp_position() const { return grasp_position_; }

  /// Digest (FNV-1a) of everything the Hessian of Pi reads: stiffness, rest geometry and
  /// curvature, clamp, springs and cuts, held vertices, moments. Two models with equal digests
  /// differ at most in dead forces (gravity, tip and point forces, poke force), which do not
  /// enter the Hessian, so a factorisation made at a state on one is exact for the other at
  /// that state (the statics solver reuses it for a warm start after a load change).
  uint64_t hessian_digest() const { return hessian_digest_; }

  /// Material frame of edge j in a state (reference frame rotated by theta_j).
  EdgeFrame MaterialFrame(const RodState& state, int j) const;

  /// Index of a free dof in the banded ordering: block j = [x_{j+1} (3), theta_j (1)].
  static int VertexDof(int i) { return 4 * (i - 1); }   ///< first of x_i's three dofs, i >= 1
  static int TwistDof(int j) { return 4 * j + 3; }      ///< j = n: an end clamp's ghost twist

 private:
  void BuildVertices();
  void PlaceHeldPoints();
  // Calls visit(gap [m], rod between [m], earlier point's name, later point's name) for each
  // pair of consecutive held points, the clamp first.
  void ForEachHeldSpan(const std::function<void(double, double, const std::string&,
                                                const std::string&)>& visit) const;
  void SetUpSymmetry();
  // The constructor's steps, in its order (each refuses what it cannot represent).
  void SetUpEnds();
  void SetUpRestGeometry();
  // The sizes of the lumped loads, for the load checks and the load scale.
  struct Loads {
    double weight = 0.0;           // [N] the rod's weight
    double point_force_sum = 0.0;  // [N] sum of |point force| (pokes included)
    double moment_sum = 0.0;       // [N m] sum of |moment|, tip moments included
  };
  Loads LumpLoads();
  void SetUpSpringZones();
  void RequireCarryable(const Loads& loads) const;
  uint64_t HessianDigest() const;
  double ForceScale(const Loads& loads) const;

  RodSpec rod_;
  Material material_;
  LoadCase case_;
  Vec3 gravity_;
  int n_ = 0;
  double length_ = 0.0, min_edge_ = 0.0;
  std::vector<double> rest_edge_, voronoi_, arc_, vertex_mass_;
  std::vector<Vec3> rest_curvature_;  // per bending vertex (rest_curvature(i))
  bool curved_ = false;
  Vec3 clamp_p_, clamp_d3_, clamp_d1_;
  bool end_clamp_ = false, end_twist_held_ = false;
  bool symmetric_ = false;
  Vec3 sym_point_ = Vec3::Zero(), sym_normal_ = Vec3::UnitX();
  double crossing_length_ = 0.0;
  Vec3 end_d3_ = Vec3::Zero(), end_d1_ = Vec3::Zero();
  Mat3X vertex_forces_;
  std::vector<EdgeMoment> edge_moments_;
  double force_scale_ = 1.0;
  std::vector<SpringZone> zones_;
  std::vector<std::vector<double>> zone_length_;
  Mat3X anchor_;
  std::vector<HeldVertex> held_;
  std::vector<int> held_of_vertex_;
  std::vector<char> held_dofs_;
  int grasp_vertex_ = -1;
  Vec3 grasp_position_ = Vec3::Zero();
  uint64_t hessian_digest_ = 0;
};

/// The small-strain envelope of the rod model [-]: a discrete elastic rod's stretch energy and
/// its bending and twisting (per unit rest length) assume edges near their rest length. An edge
/// stretched or compressed by more than this is outside the model's range (held points pulled
/// apart, a load the material would not carry, EA in the wrong unit): `simulate`'s statics warn
/// about it, a moving case stops there, and the runtime's grasp is held within it by default
/// (RuntimeOptions::max_strain). Declared once.
inline constexpr double kSmallStrainLimit = 0.1;

/// The largest |e_j| / l_j - 1 in magnitude of a state of `model`'s rod, and (when `edge` is
/// given) the edge where it is.
double LargestEdgeStrain(const RodModel& model, const RodState& state, int* edge = nullptr);

/// The value at arc length `at` [m] of a rest-curvature profile (RodSpec::rest_curvature_s /
/// rest_curvature_profile): linear between its points, constant beyond them, zero when empty.
/// How RodModel places the profile on its bending vertices (and, being linear in the values,
/// how a fitted knot's derivative is placed on them).
Vec3 RestCurvatureProfileAt(const std::vector<double>& s, const std::vector<Vec3>& profile,
                            double at);

/// The intrinsic curvature profile of a centre-line at rest (`rod.rest_shape`, docs/model.md,
/// "Rest shape"): at each interior point the discrete curvature binormal
/// 2 t_k-1 x t_k / (1 + t_k-1 . t_k) over the point's Voronoi length, resolved in the material
/// frame carried along the curve by parallel transport (no rest twist) from d1 = `normal` made
/// perpendicular to the first tangent: (k1°, k2°, 0) at the point's arc length. The arc lengths
/// are `s` when given (one per point), else the polyline's, scaled to `length` either way. For
/// RodSpec::rest_curvature_s / rest_curvature_profile. Throws std::invalid_argument for fewer than
/// 3 points, coincident points, non-finite values or a normal along the first tangent.
void RestCurvatureOfCentreline(const std::vector<double>& s, const Mat3X& points,
                               const Vec3& normal, double length,
                               std::vector<double>* profile_s, std::vector<Vec3>* profile);

}  // namespace rodfit
