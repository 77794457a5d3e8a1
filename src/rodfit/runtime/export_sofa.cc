// `--format sofa`: a SOFA scene (XML) that loads as it is (runSofa FILE): the root node with
// gravity and the time step, the RequiredPlugin lines of every component used, an implicit Euler
// solver with Rayleigh damping and a direct linear solver, the rod as a chain of Rigid3d frames
// with BeamFEMForceField (SOFA's own Timoshenko beam, in Sofa.Component.SolidMechanics.FEM.Elastic:
// no plugin to build, what SOFA users load for a beam), its mass, and its held ends as projective
// constraints. Component and data names as in SOFA v23.06 and later (FixedProjectiveConstraint,
// PartialFixedProjectiveConstraint; the v23.06 release renamed FixedConstraint and
// PartialFixedConstraint). The Cosserat plugin's BeamHookeLawForceField with the same constants
// is given in a comment for users of that plugin.
//
// Constants of a solid round section of radius r with the fitted stiffnesses
// (DeriveRoundSection): E = (B1 + B2) / 2 / I, G = GJ / J, nu = E / (2 G) - 1, I = pi r^4 / 4,
// J = 2 I. Damping: rayleighStiffness = bend_damping / B1 [s] (Kelvin-Voigt viscosity over
// stiffness), rayleighMass = damping / linear_density [1/s].
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include <Eigen/Geometry>

#include "export_format.h"
#include "rodfit/model/material_parameters.h"

namespace rodfit {
namespace {

// Rigid3d: position and orientation (qx qy qz qw) per vertex; a SOFA beam runs along its local
// x, so the frame's columns are (d3, d1, d2) of the edge leaving the vertex (the last vertex: the
// edge arriving).
std::string SofaFrames(const ExportNumbers& num, const RodModel& on, const RodState& state,
                       const char* field) {
  std::ostringstream f;
  for (int i = 0; i < on.num_vertices(); ++i) {
    const EdgeFrame e = on.MaterialFrame(state, std::min(i, on.num_edges() - 1));
    Eigen::Matrix3d r;
    r << e.d3, e.d1, e.d2;
    const Eigen::Quaterniond q(r);
    f << (i ? "  " : "") << num(state.x(0, i), field) << " " << num(state.x(1, i), field) << " "
      << num(state.x(2, i), field) << " " << num(q.x(), field) << " " << num(q.y(), field)
      << " " << num(q.z(), field) << " " << num(q.w(), field);
  }
  return f.str();
}

// The file's leading comment: the section constants, the damping mapping, the mass density.
void WriteSofaComment(const Profile& p, const ExportNumbers& num, const RoundSectionConstants& c,
                      std::ostringstream* o) {
  const RodSpec& rod = p.scene.rod;
  std::ostringstream& out = *o;
  out << "<?xml version=\"1.0\"?>\n"
      << "<!-- rodfit export (format sofa) of " << XmlCommentText(p.path) << " (profile version " << p.version
      << ", fitted by rodfit " << XmlCommentText(p.rodfit_version) << "). SI units: m, kg, s, N, Pa.\n"
      << "     Load with runSofa (SOFA v23.06 or later). Constants of a solid round section of "
         "radius " << num(rod.radius, "radius") << " m with the fitted stiffnesses:\n"
      << "     E = (B1 + B2) / 2 / I, nu = E / (2 G) - 1 with G = GJ / J, I = pi r^4 / 4, "
         "J = 2 I.\n";
  if (!c.consistent)
    out << "     WARNING: the stiffnesses are not those of a solid round section of one material ("
        << c.inconsistency << "); youngModulus reproduces the bending stiffness, EA and GJ "
           "will differ from the fitted ones.\n";
  out << "     Rayleigh damping: rayleighStiffness = bend_damping / B1 [s] (Kelvin-Voigt "
         "viscosity over stiffness), rayleighMass = damping / linear_density [1/s].\n"
      << "     As a material density for components that take one: massDensity=\""
      << num(rod.linear_density / (M_PI * rod.radius * rod.radius), "massDensity")
      << "\" [kg/m^3] = linear_density / (pi r^2). -->\n";
}

std::string WriteSofa(const ExportInput& input) {
  const Profile& p = input.profile;
  const ExportNumbers num(p, "sofa");
  const RodModel model = ExportModel(p);
  const RodState rest = model.RestState();
  const CaseSolution held = ExportHeldShape(p);
  const RodSpec& rod = p.scene.rod;
  const Material& m = p.scene.material;
  if (!(rod.radius > 0.0))
    throw ProfileError(p.path, "rod.radius", "is 0: SOFA's beams need the rod's radius");
  const double dt = input.options.time_step > 0.0 ? input.options.time_step : kDefaultExportTimeStep;
  const RoundSectionConstants c = DeriveRoundSection(m, rod.radius);
  const Vec3& g = p.scene.gravity;
  std::ostringstream out;
  WriteSofaComment(p, num, c, &out);
  out << "<Node name=\"root\" gravity=\"" << num(g.x(), "gravity") << " " << num(g.y(), "gravity")
      << " " << num(g.z(), "gravity") << "\" dt=\"" << num(dt, "dt") << "\">\n";
  // One line per module, each naming the components it provides here.
  out << "  <RequiredPlugin name=\"Sofa.Component.ODESolver.Backward\"/>  <!-- EulerImplicitSolver -->\n"
         "  <RequiredPlugin name=\"Sofa.Component.LinearSolver.Direct\"/>  <!-- SparseLDLSolver -->\n"
         "  <RequiredPlugin name=\"Sofa.Component.Topology.Container.Dynamic\"/>  <!-- EdgeSetTopologyContainer -->\n"
         "  <RequiredPlugin name=\"Sofa.Component.StateContainer\"/>  <!-- MechanicalObject -->\n"
         "  <RequiredPlugin name=\"Sofa.Component.Mass\"/>  <!-- UniformMass -->\n"
         "  <RequiredPlugin name=\"Sofa.Component.SolidMechanics.FEM.Elastic\"/>  <!-- BeamFEMForceField -->\n"
         "  <RequiredPlugin name=\"Sofa.Component.Constraint.Projective\"/>  <!-- FixedProjectiveConstraint, PartialFixedProjectiveConstraint -->\n"
         "  <DefaultAnimationLoop/>\n";
  out << "  <Node name=\"rodfit_rod\">\n";
  out << "    <EulerImplicitSolver rayleighStiffness=\""
      << num(m.bend_damping / m.B1(), "rayleighStiffness") << "\" rayleighMass=\""
      << num(rod.linear_density > 0.0 ? m.damping / rod.linear_density : 0.0, "rayleighMass")
      << "\"/>\n";
  out << "    <SparseLDLSolver/>\n";
  out << "    <!-- " << model.num_edges() << " segments, " << model.num_vertices()
      << " vertices: position is the rod as its holders place it (the case's equilibrium), "
         "rest_position the unstressed rest shape from the clamp. -->\n";
  out << "    <EdgeSetTopologyContainer name=\"topology\" edges=\"";
  for (int j = 0; j < model.num_edges(); ++j) out << (j ? " " : "") << j << " " << j + 1;
  out << "\"/>\n";
  out << "    <MechanicalObject template=\"Rigid3d\" name=\"frames\" position=\""
      << SofaFrames(num, *held.model, held.state, "position")
      << "\"\n                      rest_position=\""
      << SofaFrames(num, model, rest, "rest_position") << "\"/>\n";
  out << "    <UniformMass totalMass=\"" << num(rod.linear_density * rod.length, "totalMass")
      << "\"/>\n";
  out << "    <BeamFEMForceField name=\"beam\" youngModulus=\""
      << num(c.youngs_modulus, "youngModulus") << "\" poissonRatio=\""
      << num(c.poisson_ratio, "poissonRatio") << "\" radius=\"" << num(rod.radius, "radius")
      << "\" radiusInner=\"0\"/>\n";
  out << "    <!-- The Cosserat plugin's equivalent: -->\n";
  out << "    <!-- <BeamHookeLawForceField crossSectionShape=\"circular\" youngModulus=\""
      << num(c.youngs_modulus, "youngModulus") << "\" poissonRatio=\""
      << num(c.poisson_ratio, "poissonRatio") << "\" radius=\"" << num(rod.radius, "radius")
      << "\" length=\"";
  for (int j = 0; j < model.num_edges(); ++j)
    out << (j ? " " : "") << num(model.rest_edge_length(j), "length");
  out << "\"/> -->\n";
  // Clamps hold position and frame (all six dofs); pins hold the position only, each where the
  // held shape has it (the projective constraints keep a dof at its initial value).
  std::string fixed, partial, fixed_names, partial_names;
  for (const ExportHolder& h : ExportHolders(model)) {
    std::string& indices = h.frame ? fixed : partial;
    std::string& names = h.frame ? fixed_names : partial_names;
    indices += (indices.empty() ? "" : " ") + std::to_string(h.vertex);
    names += (names.empty() ? "" : ", ") + h.point;
  }
  out << "    <FixedProjectiveConstraint indices=\"" << fixed << "\"/>  <!-- " << fixed_names
      << " -->\n";
  if (!partial.empty())
    out << "    <PartialFixedProjectiveConstraint indices=\"" << partial
        << "\" fixedDirections=\"1 1 1 0 0 0\"/>  <!-- " << partial_names
        << ": position only -->\n";
  out << "  </Node>\n</Node>\n";
  return out.str();
}

}  // namespace

ExportFormat SofaExport() {
  return {"sofa",
          "a SOFA scene (XML, SOFA v23.06+): gravity, time step, plugins, implicit solver, the "
          "rod as BeamFEMForceField frames, held ends as projective constraints",
          /*needs_time_step=*/false, /*takes_time_step=*/true, /*takes_overrides=*/true,
          &WriteSofa};
}

}  // namespace rodfit
