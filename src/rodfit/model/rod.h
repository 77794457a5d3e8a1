// The discrete Cosserat rod (DESIGN.md §1; Bergou et al. 2008/2010; tissue paper eqs. 6–8):
// n edges, vertices x_0..x_n, one twist angle per edge, reference frames transported in time.
//
// The clamp at s = 0 is a fixed ghost edge along the clamp tangent carrying the clamp frame.
// Vertex 0 is treated as a bending vertex between the ghost edge and edge 0 with half a Voronoi
// cell (l_0 / 2): the turning from the clamp tangent (at s = 0) to edge 0 (at s = l_0 / 2) is
// the odd reflection of the angle about the clamp, which keeps the scheme second order and
// makes an end moment close a circle. Free degrees of freedom: x_1..x_n and theta_0..theta_{n-1}.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/model/scene.h"

namespace rodfit {

using Mat3X = Eigen::Matrix3Xd;
using VecX = Eigen::VectorXd;

/// The configuration of a rod: vertices, twist angles and the time-transported reference frame.
struct RodState {
  Mat3X x;          ///< vertices x_0..x_n [m], column i
  VecX theta;       ///< twist angle of edge j against its reference frame [rad], size n
  Mat3X ref_u;      ///< reference director u_j of edge j (unit, perpendicular to ref_t_j)
  Mat3X ref_t;      ///< tangent at which ref_u_j was last transported
  VecX ref_twist;   ///< reference twist at vertex i = 0..n-1 [rad], kept continuous in time

  int num_edges() const { return static_cast<int>(theta.size()); }
  Vec3 vertex(int i) const { return x.col(i); }
};

/// Material frame of one edge: d3 the tangent, d1 and d2 the material directors.
struct EdgeFrame {
  Vec3 d1, d2, d3;
};

/// Constants of one load case on one rod: geometry, stiffness, loads (the Pinocchio "Model").
/// Built once per case; the solver's scratch lives elsewhere.
class RodModel {
 public:
  /// Throws std::invalid_argument with the reason when the inputs are not a valid rod
  /// (fewer than 2 segments, non-positive length or stiffness, clamp normal parallel to tangent).
  /// `springs`: the scene's attachment zones (none: no spring term is built). Also throws for
  /// zones or cuts outside [0, L] or reversed, overlapping zones, a zone parameter missing from
  /// material.spring_parameters, springs on a rod with intrinsic curvature, and a grasp at the
  /// clamp or off the rod.
  RodModel(const RodSpec& rod, const Material& material, const Vec3& gravity,
           const LoadCase& load_case, const std::vector<SpringZone>& springs = {});

  int num_edges() const { return n_; }
  int num_vertices() const { return n_ + 1; }
  int num_free_dofs() const { return 4 * n_; }

  double length() const { return length_; }
  double rest_edge_length(int j) const { return rest_edge_[j]; }
  /// Rest Voronoi length of the bending vertex i (0..n-1) [m]; vertex 0 has half a cell.
  double voronoi_length(int i) const { return voronoi_[i]; }
  /// Arc length of vertex i in the rest state [m].
  double arc_length(int i) const { return arc_[i]; }

  const RodSpec& rod() const { return rod_; }
  const Material& material() const { return material_; }
  const LoadCase& load_case() const { return case_; }
  const Vec3& gravity() const { return gravity_; }

  const Vec3& clamp_position() const { return clamp_p_; }
  const Vec3& clamp_tangent() const { return clamp_d3_; }   ///< unit d3 at s = 0
  const Vec3& clamp_d1() const { return clamp_d1_; }        ///< unit d1 at s = 0

  /// Lumped weight of vertex i: mass times gravity [N] (zero for a massless rod).
  Vec3 vertex_weight(int i) const { return vertex_mass_[i] * gravity_; }
  double vertex_mass(int i) const { return vertex_mass_[i]; }

  /// Dead external forces lumped on vertices (tip force, point forces, weights) [N].
  const Mat3X& vertex_forces() const { return vertex_forces_; }

  /// A characteristic force [N] of this case: the largest of the loads and the bending scale
  /// B / L^2. Solver tolerances are relative to it.
  double force_scale() const { return force_scale_; }

  /// The straight rod along the clamp tangent with the clamp frame, untwisted; with a grasp, the
  /// part up to the grasped vertex is laid straight from the clamp to the grasp position.
  RodState StraightState() const;

  // Springs (tissue paper: K(s) |r - r°|^2; cut stretches have K = 0).
  bool has_springs() const { return !zones_.empty(); }
  int num_spring_zones() const { return static_cast<int>(zones_.size()); }
  const SpringZone& spring_zone(int z) const { return zones_[z]; }
  /// Stiffness of zone z [N/m^2] from the material.
  double zone_stiffness(int z) const;
  /// Length [m] of vertex i's cell that zone z covers and no cut removes: the spring of vertex
  /// i in zone z has stiffness zone_stiffness(z) * zone_cell_length(z, i) [N/m].
  double zone_cell_length(int z, int i) const { return zone_length_[z][i]; }
  /// Rest position of vertex i, where its springs pull it (the straight rest rod).
  Vec3 spring_anchor(int i) const { return anchor_.col(i); }

  // Grasp: the grasped vertex is held (a fixed dof block); -1 without a grasp.
  int grasp_vertex() const { return grasp_vertex_; }
  const Vec3& grasp_position() const { return grasp_position_; }

  /// Digest (FNV-1a) of everything the Hessian of Pi reads: stiffness, rest geometry and
  /// curvature, clamp, tip moment, springs and cuts, grasp vertex. Two models with equal
  /// digests differ at most in dead loads (gravity, tip and point forces, poke force), which do
  /// not enter the Hessian, so a factorisation made at a state on one is exact for the other
  /// at that state (the statics solver reuses it for a warm start after a load change).
  uint64_t hessian_digest() const { return hessian_digest_; }

  /// Material frame of edge j in a state (reference frame rotated by theta_j).
  EdgeFrame MaterialFrame(const RodState& state, int j) const;

  /// Index of a free dof in the banded ordering: block j = [x_{j+1} (3), theta_j (1)].
  static int VertexDof(int i) { return 4 * (i - 1); }   ///< first of x_i's three dofs, i >= 1
  static int TwistDof(int j) { return 4 * j + 3; }

 private:
  RodSpec rod_;
  Material material_;
  LoadCase case_;
  Vec3 gravity_;
  int n_ = 0;
  double length_ = 0.0;
  std::vector<double> rest_edge_, voronoi_, arc_, vertex_mass_;
  Vec3 clamp_p_, clamp_d3_, clamp_d1_;
  Mat3X vertex_forces_;
  double force_scale_ = 1.0;
  std::vector<SpringZone> zones_;
  std::vector<std::vector<double>> zone_length_;
  Mat3X anchor_;
  int grasp_vertex_ = -1;
  Vec3 grasp_position_ = Vec3::Zero();
  uint64_t hessian_digest_ = 0;
};

}  // namespace rodfit
