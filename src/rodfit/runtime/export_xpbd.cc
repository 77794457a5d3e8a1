// `--format xpbd`: per-segment compliances of a position-based stiff rod at a given time step
// (JSON). XPBD (Macklin et al. 2016, "XPBD: position-based simulation of compliant constrained
// dynamics"): a constraint C with stiffness k has compliance alpha = 1 / k and enters each
// substep as alpha~ = alpha / dt^2. The rod's energies map onto a stiff-rod constraint set
// (stretch per segment; bend and twist per pair of neighbouring frames as angle constraints, as
// in position-based Cosserat rods, Kugelstadt & Schömer 2016, and direct position-based stiff
// rods, Deul et al. 2018):
//   stretch of segment j:  E = EA / (2 l_j) (|e| - l_j)^2      -> k = EA / l_j,  alpha = l_j / EA
//   bend/twist at vertex i: E = B / (2 l_v) (l_v kappa)^2       -> k = B / l_v,   alpha = l_v / B
// with l_v the vertex's Voronoi length (half a cell at the clamp) and (l_v kappa) the turning
// angle between the neighbouring frames [rad], measured from their rest rotation. Tissue
// springs: k = K * (the zone's share of the vertex's cell) [N/m]. The rest shape (a uniform
// `rod.rest_curvature` or `rod.rest_shape`'s knots) is each joint's rest Darboux rotation: the
// quaternion q_{i-1}^* q_i between the neighbouring material frames of the rest state (the
// clamp's frame before edge 0), as position-based Cosserat rods take it (Kugelstadt & Schömer
// 2016, the rest Darboux vector), with the intrinsic curvature (k1°, k2°, tau°) it comes from.
#include <string>

#include <Eigen/Geometry>

#include <nlohmann/json.hpp>

#include "export_format.h"

namespace rodfit {
namespace {

using nlohmann::json;

// Per bending vertex: its compliances (bend and twist, and over dt2 = time_step^2) and its rest
// rotation and curvature.
json XpbdJoints(const RodModel& model, const Material& m, const RodState& rest, double dt2) {
  json joints = json::array();
  // The rest state's material frames as rotations (columns d1, d2, d3), the clamp's first.
  auto rotation = [](const Vec3& d1, const Vec3& d2, const Vec3& d3) {
    Eigen::Matrix3d r;
    r << d1, d2, d3;
    return Eigen::Quaterniond(r).normalized();
  };
  Eigen::Quaterniond before = rotation(model.clamp_d1(), model.clamp_tangent().cross(model.clamp_d1()),
                                       model.clamp_tangent());
  for (int i = 0; i < model.num_edges(); ++i) {
    // Vertex 0 bends against the clamp (half a cell); vertex i > 0 between edges i - 1 and i.
    const double lv = model.voronoi_length(i);
    json joint = {{"vertex", i}, {"voronoi_length", lv}};
    const double a1 = lv / m.B1(), a2 = lv / m.B2(), at = lv / m.twist_stiffness;
    joint["bend_1_compliance"] = a1;
    joint["bend_2_compliance"] = a2;
    joint["twist_compliance"] = at;
    joint["bend_1_compliance_dt"] = a1 / dt2;
    joint["bend_2_compliance_dt"] = a2 / dt2;
    joint["twist_compliance_dt"] = at / dt2;
    const EdgeFrame f = model.MaterialFrame(rest, i);
    const Eigen::Quaterniond after = rotation(f.d1, f.d2, f.d3);
    Eigen::Quaterniond darboux = before.conjugate() * after;
    if (darboux.w() < 0.0) darboux.coeffs() *= -1.0;  // the short way round
    joint["rest_rotation"] = {darboux.w(), darboux.x(), darboux.y(), darboux.z()};
    const Vec3 k = model.rest_curvature(i);
    joint["rest_curvature"] = {k.x(), k.y(), k.z()};
    before = after;
    joints.push_back(joint);
  }
  return joints;
}

// Per vertex: rest and start positions and mass; a held vertex fixed where its holder holds it.
json XpbdVertices(const RodModel& model, const RodState& rest, const CaseSolution& held) {
  json vertices = json::array();
  for (int i = 0; i < model.num_vertices(); ++i) {
    const Vec3 x = held.state.x.col(i);
    vertices.push_back({{"index", i},
                        {"rest_position", {rest.x(0, i), rest.x(1, i), rest.x(2, i)}},
                        {"start_position", {x.x(), x.y(), x.z()}},
                        {"mass", model.vertex_mass(i)},
                        {"fixed", false}});
  }
  // A held vertex is fixed where its holder holds it (start_position), not at rest_position; a
  // clamp holds the frame of the edge next to it too.
  for (const ExportHolder& holder : ExportHolders(model)) {
    const int vertex = holder.vertex;
    json& v = vertices[vertex];
    v["fixed"] = true;
    v["held_by"] = holder.point;
    if (holder.frame) {  // the holder's own frame: the clamp's, or the end clamp's target
      const Vec3 t = vertex == 0 ? model.clamp_tangent() : model.end_tangent();
      v["held_frame"] = {{"tangent", {t.x(), t.y(), t.z()}}};
      if (vertex == 0 || model.end_twist_held()) {
        const Vec3 d1 = vertex == 0 ? model.clamp_d1() : model.end_d1();
        v["held_frame"]["d1"] = {d1.x(), d1.y(), d1.z()};
      }
    }
  }
  return vertices;
}

std::string WriteXpbd(const ExportInput& input) {
  const Profile& p = input.profile;
  const double time_step = input.options.time_step;  // required: Export() checked it
  const RodModel model = ExportModel(p);
  const RodState rest = model.RestState();
  const CaseSolution held = ExportHeldShape(p);
  const Material& m = p.scene.material;
  const double dt2 = time_step * time_step;
  json doc;
  doc["format"] = "rodfit-xpbd";
  doc["profile"] = p.path;
  doc["time_step"] = time_step;
  doc["units"] = {{"length", "m"}, {"mass", "kg"}, {"time", "s"},
                  {"stretch_compliance", "m/N"}, {"angle_compliance", "1/(N m)"},
                  {"compliance_dt", "alpha / dt^2, same unit over s^2"}};
  doc["formulas"] = {
      {"stretch", "alpha = rest_length / EA (constraint |x_{j+1} - x_j| - rest_length)"},
      {"bend_1", "alpha = voronoi_length / B1 (turning angle about d1 between neighbouring "
                 "frames, rad)"},
      {"bend_2", "alpha = voronoi_length / B2 (about d2)"},
      {"twist", "alpha = voronoi_length / GJ (about the tangent)"},
      {"anchor", "alpha = 1 / (K * cell length in the zone) (vertex to its rest position)"},
      {"rest_rotation", "q_{i-1}^* q_i (w, x, y, z): the rotation from the frame before the "
                        "joint (the clamp's at vertex 0) to the one after it at rest, in the "
                        "former's axes (d1, d2, d3); the identity for a rod straight at rest"},
      {"rest_curvature", "(k1, k2, tau) at rest [1/m]: the rest turn over voronoi_length"},
      {"compliance_dt", "alpha~ = alpha / time_step^2 (XPBD)"}};
  json segments = json::array();
  for (int j = 0; j < model.num_edges(); ++j) {
    const double l = model.rest_edge_length(j);
    const double alpha = l / m.stretch_stiffness;
    segments.push_back({{"index", j},
                        {"rest_length", l},
                        {"stretch_compliance", alpha},
                        {"stretch_compliance_dt", alpha / dt2}});
  }
  doc["segments"] = segments;
  doc["joints"] = XpbdJoints(model, m, rest, dt2);
  doc["vertices"] = XpbdVertices(model, rest, held);
  json anchors = json::array();
  for (int z = 0; z < model.num_spring_zones(); ++z)
    for (int i = 0; i < model.num_vertices(); ++i) {
      const double k = model.zone_stiffness(z) * model.zone_cell_length(z, i);
      if (!(k > 0.0)) continue;
      const Vec3 a = model.spring_anchor(i);
      anchors.push_back({{"vertex", i},
                         {"anchor", {a.x(), a.y(), a.z()}},
                         {"compliance", 1.0 / k},
                         {"compliance_dt", 1.0 / k / dt2}});
    }
  doc["anchors"] = anchors;
  // Damping as the engines' own parameters would take it: the Kelvin-Voigt viscosities over
  // their stiffnesses are the stiffness-proportional damping times [s].
  doc["damping"] = {{"drag_per_length", m.damping},
                    {"bend_time", m.bend_damping / m.B1()},
                    {"twist_time", m.twist_damping / m.twist_stiffness},
                    {"stretch_time", m.stretch_damping / m.stretch_stiffness}};
  ExportNumbers(p, "xpbd").Check(doc);
  return doc.dump(2) + "\n";
}

}  // namespace

ExportFormat XpbdExport() {
  return {"xpbd",
          "per-segment compliances of a position-based stiff rod at --time-step (JSON)",
          /*needs_time_step=*/true, /*takes_time_step=*/true, /*takes_overrides=*/true,
          &WriteXpbd};
}

}  // namespace rodfit
