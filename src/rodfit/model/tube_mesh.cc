// Tube surface mesh along the rod and the propagation of the cross-section's deformation onto it
// (tube_mesh.h; tissue paper §4 eqs. 12–13).
#include "rodfit/model/tube_mesh.h"

#include <algorithm>
#include <cmath>
#include <locale>
#include <sstream>
#include <stdexcept>

#include "rodfit/model/rod.h"

namespace rodfit {
namespace {

constexpr double kTwoPi = 6.283185307179586;

using Vec3d = Eigen::Vector3d;

// Falloff of eqs. 12–13: (1 - d/h)^2 inside the reach h, zero beyond.
double Falloff(double d, double h) {
  const double r = 1.0 - d / h;
  return r > 0.0 ? r * r : 0.0;
}

}  // namespace

VertexFrames RodVertexFrames(const RodModel& model, const RodState& state) {
  VertexFrames f;
  RodVertexFrames(model, state, &f);
  return f;
}

void RodVertexFrames(const RodModel& model, const RodState& state, VertexFrames* frames) {
  const int n = model.num_edges();
  VertexFrames& f = *frames;
  f.centre = state.x;
  f.d1.resize(3, n + 1);
  f.d2.resize(3, n + 1);
  // Each vertex needs the frames of its two edges: the previous edge's is carried over.
  EdgeFrame before = model.MaterialFrame(state, 0);
  for (int i = 0; i <= n; ++i) {
    const EdgeFrame after = i < n ? model.MaterialFrame(state, i) : before;
    Vec3d t, d1;
    if (i == 0 || i == n) {
      const EdgeFrame& e = i == 0 ? after : before;
      t = e.d3;
      d1 = e.d1;
    } else {
      const EdgeFrame &a = before, &b = after;
      t = (a.d3 + b.d3).normalized();  // the edges never fold back onto each other
      d1 = a.d1 + b.d1;
      d1 -= d1.dot(t) * t;
      // The sum cancels only for a half-turn of twist between neighbouring edges.
      if (d1.squaredNorm() < 1e-16) d1 = b.d1 - b.d1.dot(t) * t;
      d1.normalize();
    }
    f.d1.col(i) = d1;
    f.d2.col(i) = t.cross(d1);
    before = after;
  }
}

TubeMesh BuildTube(const VertexFrames& frames, double radius, int ring_vertices) {
  TubeMesh mesh;
  BuildTube(frames, radius, ring_vertices, &mesh);
  return mesh;
}

void BuildTube(const VertexFrames& frames, double radius, int ring_vertices, TubeMesh* out) {
  const int rings = static_cast<int>(frames.centre.cols());
  if (rings < 2) throw std::invalid_argument("a tube needs at least 2 rings");
  if (frames.d1.cols() != rings || frames.d2.cols() != rings) {
    throw std::invalid_argument("frames must have one column per ring");
  }
  if (ring_vertices < 3) throw std::invalid_argument("a tube ring needs at least 3 vertices");
  if (!(radius > 0.0)) throw std::invalid_argument("tube radius must be positive");
  TubeMesh& mesh = *out;
  // The triangles depend on the shape only: rebuilt when it changed.
  const size_t triangles = static_cast<size_t>(2 * (rings - 1) * ring_vertices);
  const bool same_shape = mesh.rings == rings && mesh.ring_vertices == ring_vertices &&
                          mesh.triangles.size() == triangles;
  mesh.rings = rings;
  mesh.ring_vertices = ring_vertices;
  mesh.radius = radius;
  mesh.vertices.resize(3, rings * ring_vertices);
  for (int m = 0; m < ring_vertices; ++m) {
    const double a = kTwoPi * m / ring_vertices;
    const double c = std::cos(a), s = std::sin(a);
    for (int i = 0; i < rings; ++i) {
      mesh.vertices.col(mesh.VertexIndex(i, m)) =
          frames.centre.col(i) + radius * (c * frames.d1.col(i) + s * frames.d2.col(i));
    }
  }
  if (same_shape) return;
  // Quad (i, m), (i, m+1), (i+1, m+1), (i+1, m) split along its (i, m)-(i+1, m+1) diagonal; with
  // d1, d2, d3 right-handed both triangles face outward.
  mesh.triangles.clear();
  for (int i = 0; i + 1 < rings; ++i) {
    for (int m = 0; m < ring_vertices; ++m) {
      const int a = mesh.VertexIndex(i, m), b = mesh.VertexIndex(i, m + 1);
      const int c = mesh.VertexIndex(i + 1, m + 1), d = mesh.VertexIndex(i + 1, m);
      mesh.triangles.emplace_back(a, b, c);
      mesh.triangles.emplace_back(a, c, d);
    }
  }
}

TubeMesh BuildTube(const RodModel& model, const RodState& state, double radius,
                   int ring_vertices) {
  return BuildTube(RodVertexFrames(model, state), radius, ring_vertices);
}

std::vector<std::vector<int>> MeshNeighbours(const TubeMesh& mesh) {
  std::vector<std::vector<int>> nb(mesh.num_vertices());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int r = 0; r < 3; ++r) {
      const int a = t[r], b = t[(r + 1) % 3];
      nb[a].push_back(b);
      nb[b].push_back(a);
    }
  }
  for (auto& v : nb) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
  }
  return nb;
}

namespace {

// Eq. 12: ws->selected, the vertices of the edges that the rest curve (radius R about the
// section's centre) comes across, within h of it; ws->reached marks them.
void SelectCrossedVertices(const TubeMesh& mesh, const SectionPlacement& section, double R,
                           double h, const std::vector<std::vector<int>>& neighbours,
                           PropagationWorkspace* workspace) {
  PropagationWorkspace& ws = *workspace;
  const int V = mesh.num_vertices();
  const Vec3d c = section.centre;
  const Vec3d normal = section.normal();
  // A vertex within a hair of the plane counts as on it, so a section through a ring selects
  // both neighbouring rings alike.
  const double on_plane = 1e-9 * R;
  std::vector<double>& side = ws.side;
  side.resize(V);
  for (int v = 0; v < V; ++v) {
    const double s = (mesh.vertices.col(v) - c).dot(normal);
    side[v] = std::abs(s) <= on_plane ? 0.0 : s;
  }
  std::vector<int>& selected = ws.selected;
  selected.clear();
  std::vector<char>& reached = ws.reached;
  reached.assign(V, 0);
  for (int a = 0; a < V; ++a) {
    for (int b : neighbours[a]) {
      if (b < a) continue;
      const double sa = side[a], sb = side[b];
      if (sa * sb > 0.0) continue;
      const Vec3d pa = mesh.vertices.col(a), pb = mesh.vertices.col(b);
      const Vec3d cross = (sa == sb) ? Vec3d(0.5 * (pa + pb)) : Vec3d(pa + sa / (sa - sb) * (pb - pa));
      const Vec3d q = cross - c;
      const double in_plane = (q - q.dot(normal) * normal).norm();
      if (std::abs(in_plane - R) >= h) continue;  // another part of the tube crossing the plane
      for (int v : {a, b}) {
        if (!reached[v]) {
          reached[v] = 1;
          selected.push_back(v);
        }
      }
    }
  }
}

// Eq. 13, front by front from the active vertices (ws->active: the selected ones moved by at
// least the threshold): each front's vertices move by the falloff-weighted mean of their active
// neighbours' moves, while that is above the threshold.
void PropagateFronts(const TubeMesh& mesh, double h, double threshold,
                     const std::vector<std::vector<int>>& neighbours,
                     PropagationWorkspace* workspace, LocalDeformation* result) {
  PropagationWorkspace& ws = *workspace;
  LocalDeformation& out = *result;
  const int V = mesh.num_vertices();
  std::vector<char>& reached = ws.reached;
  std::vector<int>& active = ws.active;
  std::vector<char>& in_active = ws.in_active;
  in_active.assign(V, 0);
  std::vector<int>& candidates = ws.candidates;
  std::vector<int>& next = ws.next;
  out.stopped_by_threshold = true;
  for (int k = 1; !active.empty() && k <= V; ++k) {
    for (int v : active) in_active[v] = 1;
    candidates.clear();
    for (int v : active) {
      for (int w : neighbours[v]) {
        if (!reached[w]) {
          reached[w] = 1;
          candidates.push_back(w);
        }
      }
    }
    if (candidates.empty()) {
      out.stopped_by_threshold = false;  // ran out of mesh with moves still above the threshold
      break;
    }
    next.clear();
    for (int w : candidates) {
      Vec3d sum = Vec3d::Zero();
      int count = 0;
      for (int v : neighbours[w]) {
        if (!in_active[v]) continue;
        const double e = (mesh.vertices.col(w) - mesh.vertices.col(v)).norm();
        sum += Falloff(e, h) * out.displacement.col(v);
        ++count;
      }
      const Vec3d move = sum / count;  // count >= 1: w was reached from an active vertex
      if (move.norm() >= threshold) {
        out.displacement.col(w) = move;
        out.front[w] = k;
        next.push_back(w);
      }
    }
    for (int v : active) in_active[v] = 0;
    if (!next.empty()) out.fronts = k;
    active.swap(next);
  }
}

}  // namespace

LocalDeformation PropagateLocalDeformation(const TubeMesh& mesh, const SectionPlacement& section,
                                           const SectionSpec& spec, const RingResult& ring) {
  PropagationWorkspace workspace;
  LocalDeformation out;
  PropagateLocalDeformation(mesh, section, spec, ring, &workspace, &out);
  return out;
}

// Eq. 12's selection and eq. 13's fronts (the functions above) share the reached set in the
// workspace and the displacement they build.
void PropagateLocalDeformation(const TubeMesh& mesh, const SectionPlacement& section,
                               const SectionSpec& spec, const RingResult& ring,
                               PropagationWorkspace* workspace, LocalDeformation* result) {
  if (!spec.Check(nullptr)) {  // the message is only built on failure: it allocates
    std::string why;
    spec.Check(&why);
    throw std::invalid_argument(why);
  }
  const int N = spec.nodes;
  if (ring.rest.cols() != N || ring.nodes.cols() != N) {
    throw std::invalid_argument("ring result must have section.nodes nodes");
  }
  const int V = mesh.num_vertices();
  const double R = spec.radius;
  const double h = spec.influence_length();
  const double threshold = spec.stop_threshold();
  const Vec3d c = section.centre, d1 = section.d1, d2 = section.d2;
  const Eigen::Matrix2Xd& rest = ring.rest;
  const Eigen::Matrix2Xd& nodes = ring.nodes;

  PropagationWorkspace& ws = *workspace;
  if (ws.rings != mesh.rings || ws.ring_vertices != mesh.ring_vertices ||
      ws.neighbours.size() != static_cast<size_t>(V)) {
    ws.neighbours = MeshNeighbours(mesh);
    ws.rings = mesh.rings;
    ws.ring_vertices = mesh.ring_vertices;
    for (std::vector<int>* list : {&ws.selected, &ws.active, &ws.next, &ws.candidates})
      list->reserve(V);  // a list holds each vertex at most once
  }
  LocalDeformation& out = *result;
  out.mesh = mesh;  // the storage of an earlier mesh of this shape is reused
  out.displacement.setZero(3, V);
  out.front.assign(V, -1);
  out.fronts = 0;
  const auto& neighbours = ws.neighbours;

  // The curve's displacement at the material angle of p, and p's distance to the rest circle.
  auto curve_move = [&](const Vec3d& p, double* d) {
    const Vec3d q = p - c;
    const double x = q.dot(d1), y = q.dot(d2);
    // On the axis every point of the circle is equally close; take angle 0.
    double theta = (x * x + y * y > 1e-24 * R * R) ? std::atan2(y, x) : 0.0;
    if (theta < 0.0) theta += kTwoPi;
    const Vec3d closest = c + R * (std::cos(theta) * d1 + std::sin(theta) * d2);
    *d = (p - closest).norm();
    const double pos = theta / kTwoPi * N;
    const int k0 = std::min(static_cast<int>(pos), N - 1);
    const double t = pos - k0;
    const int k1 = (k0 + 1) % N;
    const Eigen::Vector2d u = (1.0 - t) * (nodes.col(k0) - rest.col(k0)) +
                              t * (nodes.col(k1) - rest.col(k1));
    return Vec3d(u.x() * d1 + u.y() * d2);
  };

  SelectCrossedVertices(mesh, section, R, h, neighbours, &ws);
  const std::vector<int>& selected = ws.selected;
  // The "selected" vertices: moved by at least the threshold.
  std::vector<int>& active = ws.active;
  active.clear();
  for (int v : selected) {
    double d = 0.0;
    const Vec3d move = curve_move(mesh.vertices.col(v), &d);
    out.displacement.col(v) = Falloff(d, h) * move;
    out.front[v] = 0;
    if (out.displacement.col(v).norm() >= threshold) active.push_back(v);
  }

  PropagateFronts(mesh, h, threshold, neighbours, &ws, &out);
  out.mesh.vertices += out.displacement;
}

std::string FormatObj(const TubeMesh& mesh) {
  std::ostringstream os;
  os.imbue(std::locale::classic());
  os.precision(12);
  os << "# rodfit tube mesh: " << mesh.rings << " rings x " << mesh.ring_vertices
     << " vertices, radius " << mesh.radius << " m\n";
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    os << "v " << mesh.vertices(0, v) << ' ' << mesh.vertices(1, v) << ' ' << mesh.vertices(2, v)
       << '\n';
  }
  for (const Eigen::Vector3i& t : mesh.triangles) {
    os << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  }
  return os.str();
}

}  // namespace rodfit
