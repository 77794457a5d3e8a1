// Exports of a profile to other engines' terms (rodfit/runtime/export.h).
//
// XPBD (Macklin et al. 2016, "XPBD: position-based simulation of compliant constrained
// dynamics"): a constraint C with stiffness k has compliance alpha = 1 / k and enters each
// substep as alpha~ = alpha / dt^2. The rod's energies map onto a stiff-rod constraint set
// (stretch per segment; bend and twist per pair of neighbouring frames as angle constraints, as
// in position-based Cosserat rods, Kugelstadt & Schömer 2016, and direct position-based stiff
// rods, Deul et al. 2018):
//   stretch of segment j:  E = EA / (2 l_j) (|e| - l_j)^2      -> k = EA / l_j,  alpha = l_j / EA
//   bend/twist at vertex i: E = B / (2 l_v) (l_v kappa)^2       -> k = B / l_v,   alpha = l_v / B
// with l_v the vertex's Voronoi length (half a cell at the clamp) and (l_v kappa) the turning
// angle between the neighbouring frames [rad]. Tissue springs: k = K * (the zone's share of
// the vertex's cell) [N/m].
#include "rodfit/runtime/export.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "rodfit/model/material_parameters.h"
#include "rodfit/model/rod.h"
#include "rodfit/solve/case_solve.h"

namespace rodfit {
namespace {

std::string Num(double v) {
  char buffer[40];
  std::snprintf(buffer, sizeof(buffer), "%.17g", v);
  return buffer;
}

// The rod with its held ends and nothing else: its rest shape and lumped constants.
RodModel BareModel(const Profile& p) {
  return RodModel(p.scene.rod, p.scene.material, p.scene.gravity, p.scene.cases.front(),
                  p.scene.springs);
}

// The rod as its holders place it: the profile's case solved to equilibrium (its held points at
// their targets, under gravity and the springs). Held points other than the clamp sit where the
// case holds them, not where the straight rest shape would put them, so an engine must start
// from this shape. Throws std::invalid_argument when the case cannot be solved.
CaseSolution HeldShape(const Profile& p) {
  CaseSolution sol = SolveCase(p.scene, 0, nullptr);
  if (!sol.ok())
    throw std::invalid_argument("the profile's case (its held ends) cannot be solved to "
                                "equilibrium for the held shape: " + sol.summary.BriefReport());
  return sol;
}

// One held vertex as an export names it: the holder, and whether it holds the frame too.
struct Holder {
  std::string point;     // clamp, end_clamp, end_pin, pins[k], grasp
  bool frame = false;    // a clamp: position and orientation; else position only
};
std::vector<std::pair<int, Holder>> Holders(const RodModel& model) {
  std::vector<std::pair<int, Holder>> out = {{0, {"clamp", true}}};
  for (const HeldVertex& h : model.held())
    out.push_back({h.vertex, {h.Label(), h.kind == HeldVertex::Kind::kEndClamp}});
  return out;
}

}  // namespace

std::string FormatSofaSnippet(const Profile& p) {
  const RodModel model = BareModel(p);
  const RodState rest = model.RestState();
  const CaseSolution held = HeldShape(p);
  const RodSpec& rod = p.scene.rod;
  const Material& m = p.scene.material;
  if (!(rod.radius > 0.0))
    throw std::invalid_argument("the profile's rod has no radius: SOFA's beams need one");
  const RoundSectionConstants c = DeriveRoundSection(m, rod.radius);
  const double mass_density = rod.linear_density / (M_PI * rod.radius * rod.radius);
  std::ostringstream out;
  out << "<!-- rodfit export (format sofa) of " << p.path << " (profile version " << p.version
      << ", fitted by rodfit " << p.rodfit_version << "). SI units: m, kg, s, N, Pa.\n"
      << "     Constants of a solid round section of radius " << Num(rod.radius)
      << " m with the fitted stiffnesses:\n"
      << "     E = (B1 + B2) / 2 / I, nu = E / (2 G) - 1 with G = GJ / J, I = pi r^4 / 4, "
         "J = 2 I.\n";
  if (!c.consistent)
    out << "     WARNING: the stiffnesses are not those of a solid round section of one material ("
        << c.inconsistency << "); youngModulus reproduces the bending stiffness, EA and GJ "
           "will differ from the fitted ones.\n";
  out << "     Rayleigh damping: rayleighStiffness = bend_damping / B1 [s] (Kelvin-Voigt "
         "viscosity over stiffness), rayleighMass = damping / linear_density [1/s]. -->\n";
  out << "<Node name=\"rodfit_rod\">\n";
  out << "  <EulerImplicitSolver rayleighStiffness=\"" << Num(m.bend_damping / m.B1())
      << "\" rayleighMass=\""
      << Num(rod.linear_density > 0.0 ? m.damping / rod.linear_density : 0.0) << "\"/>\n";
  out << "  <SparseLDLSolver/>\n";
  out << "  <!-- " << model.num_edges() << " segments, " << model.num_vertices()
      << " vertices: position is the rod as its holders place it (the case's equilibrium), "
         "rest_position the unstressed rest shape from the clamp. -->\n";
  out << "  <EdgeSetTopologyContainer name=\"topology\" edges=\"";
  for (int j = 0; j < model.num_edges(); ++j) out << (j ? " " : "") << j << " " << j + 1;
  out << "\"/>\n";
  // Rigid3d: position and orientation (qx qy qz qw) per vertex; a SOFA beam runs along its
  // local x, so the frame's columns are (d3, d1, d2) of the edge leaving the vertex (the last
  // vertex: the edge arriving).
  auto frames = [&](const RodModel& on, const RodState& state) {
    std::ostringstream f;
    for (int i = 0; i < on.num_vertices(); ++i) {
      const EdgeFrame e = on.MaterialFrame(state, std::min(i, on.num_edges() - 1));
      Eigen::Matrix3d r;
      r << e.d3, e.d1, e.d2;
      const Eigen::Quaterniond q(r);
      f << (i ? "  " : "") << Num(state.x(0, i)) << " " << Num(state.x(1, i)) << " "
        << Num(state.x(2, i)) << " " << Num(q.x()) << " " << Num(q.y()) << " " << Num(q.z())
        << " " << Num(q.w());
    }
    return f.str();
  };
  out << "  <MechanicalObject template=\"Rigid3d\" name=\"frames\" position=\""
      << frames(*held.model, held.state) << "\"\n                    rest_position=\""
      << frames(model, rest) << "\"/>\n";
  out << "  <UniformMass totalMass=\"" << Num(rod.linear_density * rod.length) << "\"/>\n";
  out << "  <!-- massDensity [kg/m^3] = linear_density / (pi r^2) -->\n";
  out << "  <BeamFEMForceField name=\"beam\" youngModulus=\"" << Num(c.youngs_modulus)
      << "\" poissonRatio=\"" << Num(c.poisson_ratio) << "\" radius=\"" << Num(rod.radius)
      << "\" radiusInner=\"0\" massDensity=\"" << Num(mass_density) << "\"/>\n";
  out << "  <!-- The Cosserat plugin's equivalent: -->\n";
  out << "  <!-- <BeamHookeLawForceField crossSectionShape=\"circular\" youngModulus=\""
      << Num(c.youngs_modulus) << "\" poissonRatio=\"" << Num(c.poisson_ratio) << "\" radius=\""
      << Num(rod.radius) << "\" length=\"";
  for (int j = 0; j < model.num_edges(); ++j)
    out << (j ? " " : "") << Num(model.rest_edge_length(j));
  out << "\"/> -->\n";
  // Clamps hold position and frame (all six dofs); pins and the grasp hold the position only.
  std::string fixed, partial, fixed_names, partial_names;
  for (const auto& [vertex, holder] : Holders(model)) {
    std::string& indices = holder.frame ? fixed : partial;
    std::string& names = holder.frame ? fixed_names : partial_names;
    indices += (indices.empty() ? "" : " ") + std::to_string(vertex);
    names += (names.empty() ? "" : ", ") + holder.point;
  }
  out << "  <FixedConstraint indices=\"" << fixed << "\"/>  <!-- " << fixed_names << " -->\n";
  if (!partial.empty())
    out << "  <PartialFixedConstraint indices=\"" << partial
        << "\" fixedDirections=\"1 1 1 0 0 0\"/>  <!-- " << partial_names
        << ": position only -->\n";
  out << "</Node>\n";
  return out.str();
}

std::string FormatXpbd(const Profile& p, double time_step) {
  if (!(time_step > 0.0) || !std::isfinite(time_step))
    throw std::invalid_argument("--time-step must be > 0");
  using nlohmann::json;
  const RodModel model = BareModel(p);
  const RodState rest = model.RestState();
  const CaseSolution held = HeldShape(p);
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
  json joints = json::array();
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
    joints.push_back(joint);
  }
  doc["joints"] = joints;
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
  for (const auto& [vertex, holder] : Holders(model)) {
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
  doc["vertices"] = vertices;
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
  return doc.dump(2) + "\n";
}

std::string FormatProfileCanonical(const std::string& profile_text) {
  return nlohmann::json::parse(profile_text).dump(2) + "\n";
}

}  // namespace rodfit
