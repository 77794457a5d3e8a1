// Tests of the tube mesh and the local-deformation propagation (model/tube_mesh.h, on rings
// solved by solve/ring.h; tissue paper §4 eqs. 12–13): the rest tube's geometry and orientation, the OBJ text, no motion without a
// force, eq. 12's falloff (1 - d/h)^2 for the vertices the section crosses, eq. 13's mean for
// every propagated vertex (recomputed here from the tube's own connectivity), and the stop at
// the threshold.
#include <cmath>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "rodfit/model/cross_section.h"
#include "rodfit/model/rod.h"
#include "rodfit/model/tube_mesh.h"
#include "rodfit/solve/ring.h"

namespace rodfit {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A straight rod along +x from the origin, d1 = +z (so d2 = d3 x d1 = -y), `segments` edges.
RodModel StraightRod(int segments, double length = 0.1) {
  RodSpec rod;
  rod.length = length;
  rod.segments = segments;
  rod.radius = 0.01;
  Material mat;
  mat.bend_stiffness = 1e-3;
  mat.twist_stiffness = 1e-3;
  mat.stretch_stiffness = 1e3;
  LoadCase c;
  c.name = "c";
  c.clamp.tangent = Vec3::UnitX();
  c.clamp.normal = Vec3::UnitZ();
  return RodModel(rod, mat, Vec3::Zero(), c);
}

SectionSpec Section(int nodes, double radius = 0.01) {
  SectionSpec s;
  s.radius = radius;
  s.nodes = nodes;
  return s;
}

// The tube's neighbours from its construction (quads (i,m)(i,m+1)(i+1,m+1)(i+1,m) cut along the
// (i,m)-(i+1,m+1) diagonal), independent of MeshNeighbours.
std::vector<int> TubeNeighbours(const TubeMesh& t, int v) {
  const int i = v / t.ring_vertices, m = v % t.ring_vertices;
  std::set<int> out;
  const int di[6] = {0, 0, 1, -1, 1, -1}, dm[6] = {1, -1, 0, 0, 1, -1};
  for (int r = 0; r < 6; ++r) {
    const int ii = i + di[r];
    if (ii < 0 || ii >= t.rings) continue;
    out.insert(t.VertexIndex(ii, m + dm[r]));
  }
  return {out.begin(), out.end()};
}

TEST(TubeMesh, RestTubeHasTheRadiusCountAndOutwardFaces) {
  const RodModel model = StraightRod(10);
  const RodState state = model.StraightState();
  const double R = 0.004;
  const int M = 12;
  const TubeMesh t = BuildTube(model, state, R, M);
  EXPECT_EQ(t.rings, 11);
  EXPECT_EQ(t.num_vertices(), 11 * M);
  EXPECT_EQ(static_cast<int>(t.triangles.size()), 2 * 10 * M);
  for (int i = 0; i < t.rings; ++i) {
    for (int m = 0; m < M; ++m) {
      const Vec3 p = t.vertices.col(t.VertexIndex(i, m));
      const Vec3 r = p - state.x.col(i);
      EXPECT_NEAR(r.norm(), R, 1e-15);
      EXPECT_NEAR(r.x(), 0.0, 1e-15);  // in the plane normal to the rod
      // Angle 2 pi m / M from d1 = +z towards d2 = -y.
      const double a = 2 * kPi * m / M;
      EXPECT_NEAR(r.z(), R * std::cos(a), 1e-15);
      EXPECT_NEAR(r.y(), -R * std::sin(a), 1e-15);
    }
  }
  double area = 0.0;
  for (const Eigen::Vector3i& f : t.triangles) {
    const Vec3 a = t.vertices.col(f[0]), b = t.vertices.col(f[1]), c = t.vertices.col(f[2]);
    const Vec3 n = (b - a).cross(c - a);
    const Vec3 centroid = (a + b + c) / 3.0;
    const Vec3 outward = centroid - Vec3(centroid.x(), 0, 0);
    EXPECT_GT(n.dot(outward), 0.0);
    area += 0.5 * n.norm();
  }
  // Lateral area of the prism on the inscribed M-gon.
  EXPECT_NEAR(area, M * 2 * R * std::sin(kPi / M) * 0.1, 1e-12);
}

TEST(TubeMesh, FollowsABentRodWithItsFrames) {
  const RodModel model = StraightRod(20);
  RodState state = model.StraightState();
  // A quarter circle of radius 0.1 / (pi/2) in the x-z plane; frames follow by transport.
  const double rho = 0.1 / (kPi / 2);
  for (int i = 0; i <= 20; ++i) {
    const double a = (kPi / 2) * i / 20;
    state.x.col(i) = Vec3(rho * std::sin(a), 0.0, rho * (1 - std::cos(a)));
  }
  state.SyncEdges();
  const double R = 0.003;
  const TubeMesh t = BuildTube(model, state, R, 10);
  const VertexFrames f = RodVertexFrames(model, state);
  for (int i = 0; i < t.rings; ++i) {
    const Vec3 d3 = f.d1.col(i).cross(f.d2.col(i));
    EXPECT_NEAR(f.d1.col(i).dot(f.d2.col(i)), 0.0, 1e-14);
    EXPECT_NEAR(f.d1.col(i).norm(), 1.0, 1e-14);
    if (i > 0 && i < 20) {
      const Vec3 tangent = (state.x.col(i + 1) - state.x.col(i - 1)).normalized();
      EXPECT_NEAR(d3.dot(tangent), 1.0, 1e-12);
    }
    for (int m = 0; m < 10; ++m) {
      const Vec3 r = t.vertices.col(t.VertexIndex(i, m)) - state.x.col(i);
      EXPECT_NEAR(r.norm(), R, 1e-15);
      EXPECT_NEAR(r.dot(d3), 0.0, 1e-15);
    }
  }
}

TEST(TubeMesh, ObjTextListsVerticesThenOneBasedFaces) {
  const RodModel model = StraightRod(3);
  const TubeMesh t = BuildTube(model, model.StraightState(), 0.01, 4);
  const std::string obj = FormatObj(t);
  std::istringstream in(obj);
  std::string line;
  int v = 0, f = 0, max_index = 0, min_index = 1 << 30;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) == 0) {
      ++v;
      EXPECT_EQ(f, 0) << "vertex after a face";
    } else if (line.rfind("f ", 0) == 0) {
      ++f;
      std::istringstream ls(line.substr(2));
      int a, b, c;
      ASSERT_TRUE(ls >> a >> b >> c);
      max_index = std::max({max_index, a, b, c});
      min_index = std::min({min_index, a, b, c});
    } else {
      EXPECT_EQ(line.rfind("#", 0), 0u) << line;
    }
  }
  EXPECT_EQ(v, 16);
  EXPECT_EQ(f, 2 * 3 * 4);
  EXPECT_EQ(min_index, 1);
  EXPECT_EQ(max_index, 16);
  // The third vertex line is vertex 2 of ring 0 (angle pi: -d1 = -z), to 12 digits.
  std::istringstream lines(obj);
  int seen = 0;
  while (seen < 3 && std::getline(lines, line)) {
    if (line.rfind("v ", 0) == 0) ++seen;
  }
  std::istringstream ls(line.substr(2));
  Vec3 p;
  ASSERT_TRUE(ls >> p.x() >> p.y() >> p.z());
  EXPECT_LT((p - t.vertices.col(2)).norm(), 1e-13);
  EXPECT_NEAR(p.z(), -0.01, 1e-15);
}

// The setting of the propagation tests: a straight rod of 50 edges (l = 2 mm) and a tube of
// radius R = 1 cm, so h = 0.5 sqrt(pi) R = 8.9 mm spans several rings and (1 - l/h)^2 = 0.60;
// the section carries 16 nodes and the mesh rings 16 vertices at the same angles.
struct Poke {
  RodModel model = StraightRod(50);
  RodState state = model.StraightState();
  SectionSpec spec = Section(16);
  TubeMesh mesh = BuildTube(model, state, spec.radius, 16);
  RingStiffness stiffness{2e-6, 10.0};  // F R^2 / kb = 2.5 for F = 0.05 N: a dent of ~10% R
};

TEST(LocalDeformation, NothingMovesWithoutAForce) {
  Poke p;
  const SectionPlacement sec = SectionAt(p.model, p.state, 0.043);
  const RingResult ring = SolveRing(p.spec, p.stiffness, Eigen::Vector2d::Zero());
  const LocalDeformation d = PropagateLocalDeformation(p.mesh, sec, p.spec, ring);
  EXPECT_EQ(d.displacement.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((d.mesh.vertices - p.mesh.vertices).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(d.fronts, 0);
  for (int v = 0; v < p.mesh.num_vertices(); ++v) EXPECT_LE(d.front[v], 0);
}

TEST(LocalDeformation, CrossedVerticesFollowEq12Falloff) {
  Poke p;
  // s = 42.6 mm lies between rings 21 and 22 (l = 2 mm), 0.3 l past ring 21.
  const double s = 0.0426;
  const SectionPlacement sec = SectionAt(p.model, p.state, s);
  EXPECT_NEAR((sec.centre - Vec3(s, 0, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((sec.d1 - Vec3::UnitZ()).norm(), 0.0, 1e-15);
  // An instrument pushing down on the top of the tube (and a little along it: dropped).
  const Vec3 force_world(0.02, 0.0, -0.05);
  const Eigen::Vector2d F = ProjectToSection(force_world, sec);
  EXPECT_NEAR(F.x(), -0.05, 1e-15);
  const RingResult ring = SolveRing(p.spec, p.stiffness, F);
  ASSERT_TRUE(ring.summary.converged) << ring.summary.BriefReport();
  EXPECT_EQ(ring.contact_node, 0);
  const LocalDeformation d = PropagateLocalDeformation(p.mesh, sec, p.spec, ring);
  const double h = p.spec.influence_length();
  ASSERT_NEAR(h, 0.5 * std::sqrt(kPi) * 0.01, 1e-15);
  const Eigen::Matrix3Xd u_world = SectionToWorld(ring.displacement(), sec) -
                                   sec.centre * Eigen::RowVectorXd::Ones(16);
  for (int v = 0; v < p.mesh.num_vertices(); ++v) {
    const int i = v / 16, m = v % 16;
    const bool crossed = (i == 21 || i == 22);
    EXPECT_EQ(d.front[v] == 0, crossed) << "vertex " << v;
    if (!crossed) continue;
    // Same angle as node m, at axial distance d from the section: p' - p = (1 - d/h)^2 u_m.
    const double dist = std::abs(p.state.x(0, i) - s);
    const double w = std::pow(1 - dist / h, 2);
    EXPECT_LT((d.displacement.col(v) - w * u_world.col(m)).norm(), 1e-15) << "vertex " << v;
  }
  // The top generator is dented by the contact node's move times the falloff.
  EXPECT_LT(d.displacement(2, p.mesh.VertexIndex(21, 0)), -0.1 * p.spec.stop_threshold());
}

TEST(LocalDeformation, SectionThroughARingMovesItExactlyWithTheCurve) {
  Poke p;
  const SectionPlacement sec = SectionAt(p.model, p.state, 0.040);  // ring 20
  const RingResult ring = SolveRing(p.spec, p.stiffness, Eigen::Vector2d(0.03, 0.02));
  ASSERT_TRUE(ring.summary.converged);
  const LocalDeformation d = PropagateLocalDeformation(p.mesh, sec, p.spec, ring);
  const Eigen::Matrix3Xd u_world = SectionToWorld(ring.displacement(), sec) -
                                   sec.centre * Eigen::RowVectorXd::Ones(16);
  const double w = std::pow(1 - 0.002 / p.spec.influence_length(), 2);
  for (int m = 0; m < 16; ++m) {
    EXPECT_LT((d.displacement.col(p.mesh.VertexIndex(20, m)) - u_world.col(m)).norm(), 1e-15);
    // Both neighbouring rings are reached by eq. 12 alike (C touches their edges at ring 20).
    for (int i : {19, 21}) {
      EXPECT_EQ(d.front[p.mesh.VertexIndex(i, m)], 0);
      EXPECT_LT((d.displacement.col(p.mesh.VertexIndex(i, m)) - w * u_world.col(m)).norm(), 1e-15);
    }
  }
}

TEST(LocalDeformation, PropagationFollowsEq13AndStopsAtTheThreshold) {
  Poke p;
  // A threshold of 0.2% sqrt(A) (35 um) lets the dent of ~1 mm travel a few rings: with the
  // diagonal neighbours (e = 4.4 mm, factor 0.25) in the mean a ring passes on about 0.4 of its
  // move.
  p.spec.stop_factor = 0.002;
  const SectionPlacement sec = SectionAt(p.model, p.state, 0.043);
  const RingResult ring = SolveRing(p.spec, p.stiffness, Eigen::Vector2d(-0.05, 0.01));
  ASSERT_TRUE(ring.summary.converged);
  const LocalDeformation d = PropagateLocalDeformation(p.mesh, sec, p.spec, ring);
  const double h = p.spec.influence_length(), tau = p.spec.stop_threshold();
  EXPECT_TRUE(d.stopped_by_threshold);
  EXPECT_GE(d.fronts, 2);  // several rings on each side
  auto active = [&](int v, int k) {
    return d.front[v] == k && d.displacement.col(v).norm() >= tau;
  };
  int propagated = 0;
  for (int v = 0; v < p.mesh.num_vertices(); ++v) {
    const int k = d.front[v];
    if (k < 1) continue;
    ++propagated;
    // Eq. 13: the mean over the previous front's selected neighbours of (1 - e/h)^2 (p' - p).
    Vec3 sum = Vec3::Zero();
    int count = 0;
    for (int w : TubeNeighbours(p.mesh, v)) {
      if (!active(w, k - 1)) continue;
      const double e = (p.mesh.vertices.col(v) - p.mesh.vertices.col(w)).norm();
      sum += std::pow(std::max(0.0, 1 - e / h), 2) * d.displacement.col(w);
      ++count;
    }
    ASSERT_GT(count, 0) << "vertex " << v;
    EXPECT_LT((d.displacement.col(v) - sum / count).norm(), 1e-16) << "vertex " << v;
    EXPECT_GE(d.displacement.col(v).norm(), tau);
    // On a straight tube the k-th front is the k-th ring beyond the two crossed rings.
    const int i = v / 16;
    EXPECT_TRUE(i == 21 - k || i == 22 + k) << "vertex " << v << " front " << k;
  }
  EXPECT_GT(propagated, 0);
  // Stop: every untouched neighbour of a selected vertex would have moved by less than tau.
  for (int v = 0; v < p.mesh.num_vertices(); ++v) {
    if (d.front[v] != -1) continue;
    EXPECT_EQ(d.displacement.col(v).norm(), 0.0);
    for (int k = 0; k <= d.fronts; ++k) {
      Vec3 sum = Vec3::Zero();
      int count = 0;
      for (int w : TubeNeighbours(p.mesh, v)) {
        if (!active(w, k)) continue;
        const double e = (p.mesh.vertices.col(v) - p.mesh.vertices.col(w)).norm();
        sum += std::pow(std::max(0.0, 1 - e / h), 2) * d.displacement.col(w);
        ++count;
      }
      if (count > 0) {
        EXPECT_LT((sum / count).norm(), tau) << "vertex " << v;
      }
    }
  }
  // The patch stays local: far rings do not move.
  for (int m = 0; m < 16; ++m) {
    EXPECT_EQ(d.displacement.col(p.mesh.VertexIndex(0, m)).norm(), 0.0);
    EXPECT_EQ(d.displacement.col(p.mesh.VertexIndex(50, m)).norm(), 0.0);
  }
}

TEST(LocalDeformation, ASmallerThresholdReachesFurther) {
  Poke p;
  const SectionPlacement sec = SectionAt(p.model, p.state, 0.043);
  const RingResult ring = SolveRing(p.spec, p.stiffness, Eigen::Vector2d(-0.05, 0.0));
  const LocalDeformation coarse = PropagateLocalDeformation(p.mesh, sec, p.spec, ring);
  SectionSpec fine = p.spec;
  fine.stop_factor = 0.001;
  const LocalDeformation far = PropagateLocalDeformation(p.mesh, sec, fine, ring);
  EXPECT_GT(far.fronts, coarse.fronts);
}

TEST(LocalDeformation, OtherPartsOfTheTubeCrossingThePlaneAreNotSelected) {
  // A rod folded into a U: x from 0 to 0.05 along +x, back along -x at z = 0.05. The section at
  // s = 0.0125 is the plane x = 0.0125, which the return leg's tube also crosses 5 cm away.
  const RodModel model = StraightRod(40);
  RodState state = model.StraightState();
  for (int i = 0; i <= 40; ++i) {
    const double s = 0.1 * i / 40;
    state.x.col(i) = s <= 0.05 ? Vec3(s, 0, 0) : Vec3(0.1 - s, 0, 0.05);
  }
  state.SyncEdges();
  // Fresh reference frames (a transport from +x to -x would be a half-turn): u = +y throughout.
  for (int j = 0; j < 40; ++j) {
    state.ref_t.col(j) = (state.x.col(j + 1) - state.x.col(j)).normalized();
    state.ref_u.col(j) = Vec3::UnitY();
  }
  const SectionSpec spec = Section(16, 0.005);
  const TubeMesh mesh = BuildTube(model, state, spec.radius, 16);
  const SectionPlacement sec = SectionAt(model, state, 0.0125);
  const RingResult ring = SolveRing(spec, {1e-6, 5.0}, Eigen::Vector2d(-0.02, 0.0));
  const LocalDeformation d = PropagateLocalDeformation(mesh, sec, spec, ring);
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    if (d.front[v] == 0) {
      EXPECT_LT(std::abs(mesh.vertices(2, v)), 2 * spec.radius) << v;
    }
    if (mesh.vertices(2, v) > 0.03) {
      EXPECT_EQ(d.displacement.col(v).norm(), 0.0) << v;
    }
  }
}

}  // namespace
}  // namespace rodfit
