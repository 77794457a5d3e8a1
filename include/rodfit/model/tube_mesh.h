// The tissue's surface: a tube swept along the (deformed) rod with its material frames, and the
// local deformation of the cross-section model propagated onto it (tissue paper §4, eqs. 12–13;
// docs/model.md, "Cross-section"). The global rod deformation carries the mesh; the ring's
// deformation is added on top:
//
//  - eq. 12: the mesh edges that the rest curve C comes across (edges crossing the section plane,
//    at a point within h of C) select their two vertices p. R^_p is the point of the rest circle
//    closest to p (distance d), R_p the same material point of the deformed curve (the ring's
//    node displacements interpolated linearly in angle), and p' = p + (1 - d/h)^2 (R_p - R^_p),
//    with the factor 0 for d >= h.
//  - eq. 13 (garbled in the seed; what is implemented): each vertex p not yet reached that is
//    joined by mesh edges to vertices p_1..p_k of the previous front takes the mean
//        p' = p + (1/k) sum_i (1 - e_i/h)^2 (p'_i - p_i),   e_i = |p - p_i| (undeformed mesh),
//    the factor 0 for e_i >= h. The seed shows a sum; the mean is used because a vertex of a
//    triangulated tube meets one or two front vertices, and a plain sum would double the move of
//    some of them and make the falloff depend on the triangulation's diagonals.
//  - The front advances until the moves fall below the threshold: only vertices that moved by at
//    least stop_factor sqrt(A) count as "selected" (they spawn the next front and enter its
//    means); a propagated vertex whose move comes out below the threshold is left where it is.
//    So every vertex moved by eq. 13 moved by at least the threshold, and the jump at the edge of
//    the deformed patch is below it. Eq. 12 vertices always take their move.
// h = h_factor sqrt(A) and the threshold are SectionSpec's (A = pi R^2).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/model/cross_section.h"

namespace rodfit {

class RodModel;
struct RodState;

/// A tube of `rings` rings of `ring_vertices` vertices (one ring per rod vertex); triangles are
/// 0-based, counter-clockwise seen from outside (outward normals). Open at both ends.
struct TubeMesh {
  int rings = 0;
  int ring_vertices = 0;       ///< M
  double radius = 0.0;         ///< [m]
  Eigen::Matrix3Xd vertices;   ///< column VertexIndex(ring, m) [m]
  std::vector<Eigen::Vector3i> triangles;

  int num_vertices() const { return static_cast<int>(vertices.cols()); }
  /// Vertex m (taken modulo M) of ring i, at angle 2 pi m / M from d1 towards d2.
  int VertexIndex(int ring, int m) const {
    return ring * ring_vertices + ((m % ring_vertices) + ring_vertices) % ring_vertices;
  }
};

/// Frames at the rod's vertices: centre x_i and unit directors d1, d2 (d3 = d1 x d2).
struct VertexFrames {
  Eigen::Matrix3Xd centre, d1, d2;
};

/// Averaged material frames at the vertices of a rod state: at an interior vertex the tangent is
/// the normalised sum of the two edge tangents and d1 the sum of the two edges' d1 made
/// perpendicular to it; the end vertices take their edge's frame.
VertexFrames RodVertexFrames(const RodModel& model, const RodState& state);
/// The same into *frames (no allocation once it has the size).
void RodVertexFrames(const RodModel& model, const RodState& state, VertexFrames* frames);

/// Sweeps a circle of `radius` with `ring_vertices` (>= 3) vertices along the frames. Throws
/// std::invalid_argument for fewer than 2 rings, M < 3 or a non-positive radius.
TubeMesh BuildTube(const VertexFrames& frames, double radius, int ring_vertices);
TubeMesh BuildTube(const RodModel& model, const RodState& state, double radius,
                   int ring_vertices);
/// The same into *mesh: its storage is reused, so a mesh of the same shape as the last one
/// allocates nothing (the runtime's per-frame mesh).
void BuildTube(const VertexFrames& frames, double radius, int ring_vertices, TubeMesh* mesh);

/// Vertex adjacency of the mesh's edges (sorted, without duplicates).
std::vector<std::vector<int>> MeshNeighbours(const TubeMesh& mesh);

struct LocalDeformation {
  TubeMesh mesh;                  ///< the input mesh with the local deformation added
  Eigen::Matrix3Xd displacement;  ///< p' - p per vertex [m]
  /// -1: untouched; 0: selected by eq. 12 (edges crossed by C); k >= 1: set by the k-th front of
  /// eq. 13 (a vertex reached but left below the threshold also has -1).
  std::vector<int> front;
  int fronts = 0;                 ///< eq. 13 fronts that moved at least one vertex
  /// True when propagation ended because every new move fell below the threshold (or nothing
  /// moved); false when it ran out of mesh first.
  bool stopped_by_threshold = true;
};

/// Scratch of PropagateLocalDeformation kept between calls on meshes of one shape (the
/// runtime's per-frame dent): the mesh's adjacency, built on the first call for a shape, and the
/// fronts' lists, reserved to the mesh's size.
struct PropagationWorkspace {
  int rings = 0, ring_vertices = 0;  ///< the shape the buffers are for
  std::vector<std::vector<int>> neighbours;
  std::vector<double> side;
  std::vector<int> selected, active, next, candidates;
  std::vector<char> reached, in_active;
};

/// Adds the ring's deformation (`ring.nodes - ring.rest`, section coordinates, nodes at angles
/// 2 pi k / N from d1) to the mesh by eqs. 12–13. `section` places the rest curve C (a circle of
/// spec.radius) in the world. Throws std::invalid_argument when the ring does not have
/// spec.nodes nodes.
LocalDeformation PropagateLocalDeformation(const TubeMesh& mesh, const SectionPlacement& section,
                                           const SectionSpec& spec, const RingResult& ring);
/// The same into *out with the scratch in *workspace: no allocation once both have been through
/// a call on a mesh of this shape.
void PropagateLocalDeformation(const TubeMesh& mesh, const SectionPlacement& section,
                               const SectionSpec& spec, const RingResult& ring,
                               PropagationWorkspace* workspace, LocalDeformation* out);

/// The mesh as Wavefront OBJ text ("v x y z" lines, then 1-based "f a b c"), locale-independent,
/// 12 significant digits. The io layer writes it to a file.
std::string FormatObj(const TubeMesh& mesh);

}  // namespace rodfit
