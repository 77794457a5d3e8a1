// The ring of the cross-section model (cross_section.h; tissue paper §4 eqs. 10–11): rest
// geometry, closed-form derivatives of the elastic energy, the dead load, the result types of
// its statics and the section's placement on the rod. The ring's Newton solve is in
// solve/ring.cc.
#include "rodfit/model/cross_section.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <Eigen/QR>

#include "rodfit/model/rod.h"

namespace rodfit {
namespace {

constexpr double kPi = 3.14159265358979323846;

using Mat2 = Eigen::Matrix2d;
using Vec2 = Eigen::Vector2d;

Vec2 Perp(const Vec2& v) { return Vec2(-v.y(), v.x()); }  // rotated by +90 degrees

Vec2 Node(const Eigen::VectorXd& u, int k) { return u.segment<2>(NodeDof(k)); }

// Hessian of the polar angle of v: d/dv (v_perp / |v|^2) = (J |v|^2 - 2 v_perp v^T) / |v|^4.
Mat2 AngleHessian(const Vec2& v) {
  Mat2 J;
  J << 0.0, -1.0, 1.0, 0.0;
  const double s = v.squaredNorm();
  return (J * s - 2.0 * Perp(v) * v.transpose()) / (s * s);
}

void Require(bool ok, const std::string& why) {
  if (!ok) throw std::invalid_argument(why);
}

}  // namespace

double SectionSpec::area() const { return kPi * radius * radius; }
double SectionSpec::influence_length() const { return h_factor * std::sqrt(area()); }
double SectionSpec::stop_threshold() const { return stop_factor * std::sqrt(area()); }

bool SectionSpec::Check(std::string* why) const {
  std::string w;
  if (!(radius > 0.0) || !std::isfinite(radius)) w = "section radius must be positive";
  else if (nodes < 8) w = "section nodes must be at least 8";
  else if (!(h_factor > 0.0) || !std::isfinite(h_factor)) w = "section h_factor must be positive";
  else if (!(stop_factor > 0.0) || !std::isfinite(stop_factor))
    w = "section stop_factor must be positive";
  if (why) *why = w;
  return w.empty();
}

bool RingStiffness::Check(std::string* why) const {
  std::string w;
  if (!(bend > 0.0) || !std::isfinite(bend)) w = "ring_bend_stiffness must be positive";
  else if (!(stretch > 0.0) || !std::isfinite(stretch))
    w = "ring_stretch_stiffness must be positive";
  if (why) *why = w;
  return w.empty();
}

RingGeometry MakeRingGeometry(const SectionSpec& spec) {
  std::string why;
  Require(spec.Check(&why), why);
  RingGeometry g;
  g.n = spec.nodes;
  g.radius = spec.radius;
  g.rest.resize(2, g.n);
  for (int k = 0; k < g.n; ++k) {
    const double a = 2.0 * kPi * k / g.n;
    g.rest.col(k) = spec.radius * Vec2(std::cos(a), std::sin(a));
  }
  g.edge.resize(g.n);
  g.voronoi.resize(g.n);
  g.rest_curvature.resize(g.n);
  g.length = 0.0;
  for (int k = 0; k < g.n; ++k) {
    g.edge[k] = (g.rest.col(g.next(k)) - g.rest.col(k)).norm();
    g.length += g.edge[k];
  }
  g.guard = 1e-9 * g.length / g.n;
  // The rest curvature by the energy's own formula (soft norms included), so that the rest
  // polygon is stress free to the last bit.
  const double d2 = g.guard * g.guard;
  for (int k = 0; k < g.n; ++k) {
    g.voronoi[k] = 0.5 * (g.edge[g.prev(k)] + g.edge[k]);
    const Vec2 a = g.rest.col(k) - g.rest.col(g.prev(k));
    const Vec2 b = g.rest.col(g.next(k)) - g.rest.col(k);
    const double len_a = std::sqrt(a.x() * a.x() + a.y() * a.y() + d2);
    const double len_b = std::sqrt(b.x() * b.x() + b.y() * b.y() + d2);
    const double tan_half = (a.x() * b.y() - a.y() * b.x()) / (len_a * len_b + a.x() * b.x() + a.y() * b.y());
    g.rest_curvature[k] = 2.0 * tan_half / g.voronoi[k];
  }
  return g;
}

double RingElasticEnergy(const RingGeometry& g, const RingStiffness& k, const Eigen::VectorXd& u,
                         Eigen::VectorXd* gradient, Eigen::MatrixXd* hessian) {
  const int n = g.n;
  assert(u.size() == 2 * n);
  if (gradient) gradient->setZero(2 * n);
  if (hessian) hessian->setZero(2 * n, 2 * n);
  const double energy = RingElasticEnergy<double>(g, k, u.data());
  // Edge i (node i to i + 1): its rest vector and its change, kept apart for precision.
  auto rest_edge = [&](int i) -> Vec2 { return g.rest.col(g.next(i)) - g.rest.col(i); };
  auto edge_change = [&](int i) -> Vec2 { return Node(u, g.next(i)) - Node(u, i); };
  if (!gradient && !hessian) return energy;
  for (int i = 0; i < n; ++i) {
    const int j = g.next(i), h = g.prev(i);
    // Stretch of edge i: E = ks L / 2 (|e|/L - 1)^2.
    {
      const Vec2 e0 = rest_edge(i), de = edge_change(i), e = e0 + de;
      const double len = e.norm();
      const Vec2 t = e / len;
      const double strain = (2.0 * e0.dot(de) + de.squaredNorm()) / (g.edge[i] * (len + g.edge[i]));
      const Vec2 ge = k.stretch * strain * t;
      if (gradient) {
        gradient->segment<2>(NodeDof(i)) -= ge;
        gradient->segment<2>(NodeDof(j)) += ge;
      }
      if (hessian) {
        const Mat2 tt = t * t.transpose();
        const Mat2 He = k.stretch / g.edge[i] * tt + k.stretch * strain / len * (Mat2::Identity() - tt);
        hessian->block<2, 2>(NodeDof(i), NodeDof(i)) += He;
        hessian->block<2, 2>(NodeDof(j), NodeDof(j)) += He;
        hessian->block<2, 2>(NodeDof(i), NodeDof(j)) -= He;
        hessian->block<2, 2>(NodeDof(j), NodeDof(i)) -= He;
      }
    }
    // Bending at node i: kappa = 2 tan(phi/2) / l with phi = angle(b) - angle(a), so
    // d phi / d a = -a_perp / |a|^2, d phi / d b = b_perp / |b|^2, d kappa / d phi = (1 + t^2) / l.
    {
      const Vec2 a = rest_edge(h) + edge_change(h), b = rest_edge(i) + edge_change(i);
      const double l = g.voronoi[i];
      const double t = (a.x() * b.y() - a.y() * b.x()) / (a.norm() * b.norm() + a.dot(b));
      const double dk = 2.0 * t / l - g.rest_curvature[i];
      const double k1 = (1.0 + t * t) / l;      // d kappa / d phi
      const double k2 = t * (1.0 + t * t) / l;  // d^2 kappa / d phi^2
      const double E_phi = k.bend * l * dk * k1;
      const double E_phiphi = k.bend * l * (k1 * k1 + dk * k2);
      const Vec2 pa = -Perp(a) / a.squaredNorm(), pb = Perp(b) / b.squaredNorm();
      // Node gradients of phi: node h: -pa, node i: pa - pb, node j: pb.
      const int nodes[3] = {h, i, j};
      const Vec2 dphi[3] = {-pa, pa - pb, pb};
      if (gradient) {
        for (int r = 0; r < 3; ++r) gradient->segment<2>(NodeDof(nodes[r])) += E_phi * dphi[r];
      }
      if (hessian) {
        // phi's Hessian in (a, b) is blockdiag(-H_ang(a), H_ang(b)); a = X_i - X_h, b = X_j - X_i.
        const Mat2 Ha = -AngleHessian(a), Hb = AngleHessian(b);
        // d a / d node = (-I, I, 0), d b / d node = (0, -I, I).
        const double sa[3] = {-1.0, 1.0, 0.0}, sb[3] = {0.0, -1.0, 1.0};
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c) {
            const Mat2 block = E_phiphi * dphi[r] * dphi[c].transpose() +
                               E_phi * (sa[r] * sa[c] * Ha + sb[r] * sb[c] * Hb);
            hessian->block<2, 2>(NodeDof(nodes[r]), NodeDof(nodes[c])) += block;
          }
        }
      }
    }
  }
  return energy;
}

int ContactNode(const RingGeometry& g, const Vec2& force) {
  int best = 0;
  double best_value = std::numeric_limits<double>::infinity();
  for (int k = 0; k < g.n; ++k) {
    // The rest nodes lie on a circle about the origin: the outward normal is X°_k / R.
    const double v = g.rest.col(k).dot(force);
    if (v < best_value) {
      best_value = v;
      best = k;
    }
  }
  return best;
}

RingLoad MakeRingLoad(const RingGeometry& g, const Vec2& force) {
  RingLoad load;
  MakeRingLoad(g, force, &load);
  return load;
}

void MakeRingLoad(const RingGeometry& g, const Vec2& force, RingLoad* load) {
  load->force = force;
  load->contact_node = -1;
  load->nodal.setZero(2 * g.n);
  load->d_nodal_d_force.setZero(2 * g.n, 2);
  if (force.squaredNorm() == 0.0) return;
  load->contact_node = ContactNode(g, force);
  for (int k = 0; k < g.n; ++k) {
    const double w = (k == load->contact_node ? 1.0 : 0.0) - g.voronoi[k] / g.length;
    load->nodal.segment<2>(NodeDof(k)) = w * force;
    load->d_nodal_d_force.block<2, 2>(NodeDof(k), 0) = w * Mat2::Identity();
  }
}

Eigen::Matrix<double, 3, Eigen::Dynamic> RingConstraints(const RingGeometry& g) {
  Eigen::Matrix<double, 3, Eigen::Dynamic> C;
  C.setZero(3, 2 * g.n);
  Vec2 centre = Vec2::Zero();
  for (int k = 0; k < g.n; ++k) centre += g.voronoi[k] / g.length * g.rest.col(k);
  for (int k = 0; k < g.n; ++k) {
    const double w = g.voronoi[k] / g.length;
    C(0, NodeDof(k)) = w;
    C(1, NodeDof(k) + 1) = w;
    // (X°_k - c°) x u_k = r_x u_y - r_y u_x.
    const Vec2 r = g.rest.col(k) - centre;
    C(2, NodeDof(k)) = -w * r.y();
    C(2, NodeDof(k) + 1) = w * r.x();
  }
  for (int r = 0; r < 3; ++r) C.row(r).normalize();
  return C;
}

Vec2 RingCentre(const RingGeometry& g, const Eigen::Matrix2Xd& nodes) {
  Vec2 c = Vec2::Zero();
  for (int k = 0; k < g.n; ++k) c += g.voronoi[k] / g.length * nodes.col(k);
  return c;
}

const char* ToString(RingTermination t) {
  switch (t) {
    case RingTermination::kZeroLoad: return "zero load";
    case RingTermination::kGradientTolerance: return "gradient below tolerance";
    case RingTermination::kStepTolerance: return "step below tolerance";
    case RingTermination::kRoundOff: return "Newton decrement below round-off";
    case RingTermination::kMaxIterations: return "iteration limit reached";
    case RingTermination::kLineSearchFailed: return "line search failed";
    case RingTermination::kNotFinite: return "energy not finite";
  }
  return "unknown";
}

std::string RingSummary::BriefReport() const {
  std::ostringstream os;
  os << "ring: " << (converged ? "converged" : "FAILED") << " (" << ToString(reason) << "), "
     << iterations << " iterations, |g|_inf " << gradient_norm << " N, Pi " << energy << " J"
     << (stable ? "" : ", unstable equilibrium");
  if (hessian_shifts > 0) os << ", " << hessian_shifts << " Hessian shifts";
  return os.str();
}

SectionPlacement SectionAt(const RodModel& model, const RodState& state, double s) {
  const double L = model.length();
  const double slack = 1e-12 * L;
  if (!(s >= -slack && s <= L + slack)) {
    throw std::invalid_argument("section arc length must lie in [0, L]");
  }
  s = std::clamp(s, 0.0, L);
  const int edges = model.num_edges();
  int j = 0;
  while (j + 1 < edges && model.arc_length(j + 1) <= s) ++j;
  const double s0 = model.arc_length(j), s1 = model.arc_length(j + 1);
  const double t = std::clamp((s - s0) / (s1 - s0), 0.0, 1.0);
  SectionPlacement p;
  p.centre = (1.0 - t) * state.x.col(j) + t * state.x.col(j + 1);
  const EdgeFrame f = model.MaterialFrame(state, j);
  p.d1 = f.d1;
  p.d2 = f.d2;
  return p;
}

Vec2 ProjectToSection(const Eigen::Vector3d& force_world, const SectionPlacement& p) {
  return Vec2(force_world.dot(p.d1), force_world.dot(p.d2));
}

Eigen::Matrix3Xd SectionToWorld(const Eigen::Matrix2Xd& points, const SectionPlacement& p) {
  Eigen::Matrix3Xd out(3, points.cols());
  for (int k = 0; k < points.cols(); ++k) {
    out.col(k) = p.centre + points(0, k) * p.d1 + points(1, k) * p.d2;
  }
  return out;
}

}  // namespace rodfit
