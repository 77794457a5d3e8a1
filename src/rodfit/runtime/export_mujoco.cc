// `--format mujoco`: an MJCF file (MuJoCo 3.x) with the rod as a composite `cable` whose bending
// and twisting come from the elasticity plugin `mujoco.elasticity.cable`.
//
// The mapping, from the plugin's source (MuJoCo 3.x, plugin/elasticity/cable.cc, Cable::Cable and
// Cable::Compute): for a capsule of radius r the plugin takes `bend` = E and `twist` = G [Pa] and
// multiplies them by the section's I = pi r^4 / 4 and J = pi r^4 / 2; the moment between two
// consecutive bodies is -(E I, E I, G J) * omega / l, omega the rotation vector between the bodies'
// frames (relative to the rest one) and l the distance between their origins. So
//   E = B / (pi r^4 / 4),  B = (B1 + B2) / 2,      G = GJ / (pi r^4 / 2),
// which gives the joint between bodies of length l the stiffness E I / l = B / l: the discrete
// rod's B / l_v at a vertex of Voronoi length l_v = l (uniform segments). The clamp is a body of
// half a segment fixed in the world (initial="none") before the rod's first segment: the plugin's
// stiffness there is B / (l / 2), rodfit's half cell at the clamp. Mass: each segment's capsule
// weighs mu * l. Joint damping: bend_damping / l [N m s/rad] (the Kelvin-Voigt viscosity of the
// bending rate over the same length). Held ends: the cable starts in rodfit's held equilibrium
// (`vertex`), an end clamp is a half-segment body welded where it is, pins and an end pin are
// `connect` constraints where they are (MuJoCo's equality constraints hold the initial relative
// pose), and the plugin's `flat` makes the rest shape straight (omega0 = 0), whatever the start.
// A curved rest shape (`rod.rest_curvature`, `rod.rest_shape`) is the plugin's reference
// configuration when the cable starts in it (flat=false: omega0 from the bodies' initial poses,
// whose turning angle at a vertex, 2 atan(kappa° l / 2), is the discrete rod's rest turn), which
// only a rod held at the clamp alone allows; a rest twist has no cable form.
//
// What the cable drops or does differently, said in the file too: stretch (the cable is
// inextensible: EA and stretch_damping are not used), the external drag per length (`damping`;
// MuJoCo has no per-length drag on a body), anisotropic bending (B1 != B2: the plugin's section is
// round), twist damping (a ball joint's damping is one value for all three axes), the end clamp's
// bending at s = L (the plugin's stiffness there is B / l, rodfit's B / (l / 2)), an end clamp
// without a normal (a weld holds the roll too). MuJoCo's open report #2208 ("Cable Composite
// Object Using Wrong Area Moment of Inertia", 2024) says measured deflections followed the
// box-section formula; the test here (tests/export/mujoco_sag.mjs) checks the circular-section
// mapping through an equivalent joint stiffness, not the plugin itself.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "export_format.h"
#include "rodfit/model/material_parameters.h"

namespace rodfit {
namespace {

// The composite cable's body names (MuJoCo's mjCComposite::AddCableBody): B_first, B_1, ...,
// B_last.
std::string BodyName(int b, int num_bodies) {
  if (b == 0) return "B_first";
  if (b == num_bodies - 1) return "B_last";
  return "B_" + std::to_string(b);
}

// What has no MJCF cable form is refused, naming the profile key: unequal segments (one geom,
// one mass per body), a curved rest shape held beyond the clamp, a rest twist.
void RequireCableForm(const Profile& p, const RodModel& model,
                      const std::vector<ExportHolder>& holders) {
  const int n = model.num_edges();
  const double l = model.rest_edge_length(0);
  for (int j = 1; j < n; ++j)
    if (std::abs(model.rest_edge_length(j) - l) > 1e-9 * l)
      throw ProfileError(p.path, "rod.vertex_s",
                         "segments of different lengths: the composite cable gives every body "
                         "one geom (one mass); export a profile with equal segments");
  // A rest shape (rod.rest_shape's knots) or a uniform rest curvature: the key that gives it.
  const char* rest_key =
      p.scene.rod.rest_curvature_s.empty() ? "rod.rest_curvature" : "rod.rest_shape";
  if (model.curved_at_rest() && holders.size() > 1)
    throw ProfileError(p.path, rest_key,
                       "a curved rest shape with held points besides the clamp has no MJCF "
                       "cable: the plugin takes a curved rest shape from the start shape, and the "
                       "equality constraints hold the start pose");
  // The cable's bodies are framed along its vertices without a twist of their own (MuJoCo's
  // cable composite), so a rest twist has nothing to be read from.
  for (int i = 0; i <= model.num_edges(); ++i)
    if (model.rest_curvature(i)[2] != 0.0)
      throw ProfileError(p.path,
                         p.scene.rod.rest_curvature[2] != 0.0 ? "rod.rest_curvature"
                                                              : "rod.rest_shape.tau_per_m",
                         "a rest twist has no MJCF cable: the composite frames its bodies along "
                         "the start shape's vertices, untwisted");
}

// The cable's numbers, from the mapping in the file comment.
struct Cable {
  double l = 0.0;          // [m] segment length
  double E = 0.0, G = 0.0; // [Pa] the plugin's bend and twist
  double body_mass = 0.0;  // [kg] per segment body
  double stable_dt = 0.0;  // [s] the explicit plugin forces' stable step
  double dt = 0.0;         // [s] the time step written
  bool end_clamp = false;  // the last body is welded (an end clamp)
  bool curved_rest = false;
};

// The file's leading comment: the mapping with this rod's numbers, and what the cable drops.
void WriteMujocoComment(const Profile& p, const ExportNumbers& num, const Cable& cable,
                        std::ostringstream* o) {
  const Material& m = p.scene.material;
  const RoundSectionConstants c = DeriveRoundSection(m, p.scene.rod.radius);
  const double l = cable.l;
  std::ostringstream& out = *o;
  out << "<!-- rodfit export (format mujoco) of " << XmlCommentText(p.path)
      << " (profile version " << p.version << ", fitted by rodfit "
      << XmlCommentText(p.rodfit_version) << "). SI units: m, kg, s, N, Pa.\n"
      << "     MuJoCo 3.x composite cable with the elasticity plugin mujoco.elasticity.cable "
         "(plugin/elasticity/cable.cc): bend = E, twist = G [Pa], times the capsule's\n"
      << "     I = pi r^4 / 4 and J = pi r^4 / 2: E = (B1 + B2) / 2 / I, G = GJ / J; joint "
         "stiffness E I / l = B / l between segments of length l = " << num(l, "l") << " m.\n"
      << "     Equivalent without the plugin (MuJoCo builds without plugins, e.g. its WebAssembly "
         "build): joint stiffness = " << num(0.5 * (m.B1() + m.B2()) / l, "joint stiffness")
      << " N m/rad (bending; twice that for the first joint, against the clamp's half segment; "
         "twist would be GJ / l = " << num(m.twist_stiffness / l, "GJ / l") << ").\n"
      << "     Mass per segment body mu l = " << num(cable.body_mass, "mass")
      << " kg; joint damping bend_damping / l. The first body (half a segment) is the clamp"
      << (cable.end_clamp ? ", the last one the end clamp (welded)" : "") << ".\n"
      << "     The cable starts in rodfit's held equilibrium; the plugin's flat=true makes the "
         "rest shape straight.\n"
      << "     Not in the cable: stretch (inextensible; EA " << num(m.stretch_stiffness, "EA")
      << " N and stretch_damping unused), the external drag per length (damping "
      << num(m.damping, "damping") << " N s/m^2 dropped), twist damping (one ball-joint damping "
         "for all axes).\n";
  if (std::abs(m.B1() - m.B2()) > kRoundSectionTolerance * std::max(m.B1(), m.B2()))
    out << "     WARNING: B1 != B2 (anisotropic bending); the plugin's round section takes their "
           "mean.\n";
  if (!c.consistent)
    out << "     Note: the stiffnesses are not those of one solid round material ("
        << XmlCommentText(c.inconsistency) << "); E and G reproduce B and GJ exactly.\n";
  if (cable.end_clamp)
    out << "     The end clamp's bending at s = L: the plugin's B / l, rodfit's B / (l / 2); a "
           "weld holds the end's roll too.\n";
  out << "     Time step " << num(cable.dt, "timestep") << " s; the plugin's forces are explicit: "
         "steps beyond about " << num(cable.stable_dt, "stable step") << " s are unstable.\n"
      << "     MuJoCo's open report #2208 (cable area moment, 2024) questions the plugin's I for "
         "capsules: check a sag against rodfit's. -->\n";
}

// Held points beyond the clamp, each where the start shape has it: an end clamp welded, pins and
// an end pin connected. The body of edge j is j + 1 (body 0 is the clamp's); its origin is
// vertex j.
std::string MujocoEquality(const ExportNumbers& num, const std::vector<ExportHolder>& holders,
                           int n, int num_bodies, const Cable& cable) {
  std::ostringstream equality;
  const std::string solref = num(2.0 * cable.dt, "solref") + " 1";  // as stiff as the step allows
  for (const ExportHolder& h : holders) {
    if (h.point == "clamp") continue;
    std::string name = h.point;  // pins[2] -> pins_2: a plain MJCF name
    for (char& ch : name)
      if (ch == '[') ch = '_';
    name.erase(std::remove(name.begin(), name.end(), ']'), name.end());
    if (h.frame) {
      equality << "    <weld name=\"" << name << "\" body1=\"B_last\" solref=\"" << solref
               << "\"/>\n";
    } else if (h.vertex == n) {
      equality << "    <connect name=\"" << name << "\" body1=\"" << BodyName(n, num_bodies)
               << "\" anchor=\"" << num(cable.l, "anchor") << " 0 0\" solref=\"" << solref
               << "\"/>\n";
    } else {
      equality << "    <connect name=\"" << name << "\" body1=\""
               << BodyName(h.vertex + 1, num_bodies) << "\" anchor=\"0 0 0\" solref=\"" << solref
               << "\"/>\n";
    }
  }
  return equality.str();
}

std::string WriteMujoco(const ExportInput& input) {
  const Profile& p = input.profile;
  const ExportNumbers num(p, "mujoco");
  const RodModel model = ExportModel(p);
  const CaseSolution held = ExportHeldShape(p);
  const RodSpec& rod = p.scene.rod;
  const Material& m = p.scene.material;
  if (!(rod.radius > 0.0))
    throw ProfileError(p.path, "rod.radius", "is 0: the cable's capsules need the rod's radius");
  const int n = model.num_edges();
  const std::vector<ExportHolder> holders = ExportHolders(model);
  RequireCableForm(p, model, holders);
  Cable cable;
  const double l = cable.l = model.rest_edge_length(0);
  cable.curved_rest = model.curved_at_rest();
  for (const ExportHolder& h : holders)
    cable.end_clamp = cable.end_clamp || (h.frame && h.vertex == n);
  const double area_moment = M_PI * std::pow(rod.radius, 4) / 4.0;  // I of the capsule
  cable.E = 0.5 * (m.B1() + m.B2()) / area_moment;
  cable.G = m.twist_stiffness / (2.0 * area_moment);
  cable.body_mass = rod.linear_density * l;
  // The stiffest joint (the clamp's, B / (l / 2)) against a segment's inertia about its end
  // (mu l^3 / 3): MuJoCo integrates the plugin's forces explicitly, so a step beyond ~2 / omega
  // blows up; the default takes a quarter of that.
  const double omega = std::sqrt(6.0 * 0.5 * (m.B1() + m.B2()) / rod.linear_density) / (l * l);
  cable.stable_dt = rod.linear_density > 0.0 ? 2.0 / omega : kDefaultExportTimeStep;
  cable.dt = input.options.time_step > 0.0
                 ? input.options.time_step
                 : std::min(kDefaultExportTimeStep, 0.25 * cable.stable_dt);

  // The start shape: rodfit's held equilibrium (flat rest), or with a curved rest shape and only
  // the clamp, the rest shape itself (the plugin's rest). A half-segment body inside the clamp
  // comes first, and one inside an end clamp last.
  const RodState start = cable.curved_rest ? model.RestState() : held.state;
  const Vec3 t0 = model.clamp_tangent();
  std::vector<Vec3> vertex = {start.x.col(0) - 0.5 * l * t0};
  for (int i = 0; i <= n; ++i) vertex.push_back(start.x.col(i));
  if (cable.end_clamp) vertex.push_back(start.x.col(n) + 0.5 * l * model.end_tangent());
  const int num_bodies = static_cast<int>(vertex.size()) - 1;

  std::ostringstream out;
  WriteMujocoComment(p, num, cable, &out);
  out << "<mujoco model=\"rodfit_rod\">\n"
      << "  <extension>\n    <plugin plugin=\"mujoco.elasticity.cable\"/>\n  </extension>\n"
      << "  <compiler autolimits=\"true\"/>\n"
      << "  <option timestep=\"" << num(cable.dt, "timestep") << "\" gravity=\""
      << num(p.scene.gravity.x(), "gravity") << " " << num(p.scene.gravity.y(), "gravity") << " "
      << num(p.scene.gravity.z(), "gravity") << "\" integrator=\"implicitfast\"/>\n"
      << "  <worldbody>\n"
      << "    <composite type=\"cable\" initial=\"none\" vertex=\"";
  for (size_t i = 0; i < vertex.size(); ++i)
    out << (i ? "  " : "") << num(vertex[i].x(), "vertex") << " " << num(vertex[i].y(), "vertex")
        << " " << num(vertex[i].z(), "vertex");
  out << "\">\n"
      << "      <plugin plugin=\"mujoco.elasticity.cable\">\n"
      << "        <config key=\"bend\" value=\"" << num(cable.E, "bend") << "\"/>\n"
      << "        <config key=\"twist\" value=\"" << num(cable.G, "twist") << "\"/>\n"
      << "        <config key=\"flat\" value=\"" << (cable.curved_rest ? "false" : "true")
      << "\"/>\n"
      << "      </plugin>\n"
      << "      <joint kind=\"main\" damping=\"" << num(m.bend_damping / l, "damping") << "\"/>\n"
      << "      <geom type=\"capsule\" size=\"" << num(rod.radius, "size") << "\" mass=\""
      << num(cable.body_mass, "mass") << "\"/>\n"
      << "    </composite>\n"
      << "  </worldbody>\n";
  const std::string equality = MujocoEquality(num, holders, n, num_bodies, cable);
  if (!equality.empty()) out << "  <equality>\n" << equality << "  </equality>\n";
  out << "</mujoco>\n";
  return out.str();
}

}  // namespace

ExportFormat MujocoExport() {
  return {"mujoco",
          "an MJCF file (MuJoCo 3.x): a composite cable with the mujoco.elasticity.cable plugin "
          "(bend = E, twist = G), mass, damping, held ends as welds and connects, gravity, time "
          "step",
          /*needs_time_step=*/false, /*takes_time_step=*/true, /*takes_overrides=*/true,
          &WriteMujoco};
}

}  // namespace rodfit
