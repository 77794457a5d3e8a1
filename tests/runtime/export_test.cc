// The export formats (rodfit/runtime/export.h): a registry whose rows the CLI reads; the checks
// every export runs before anything is written (issue 34: json accepted what sofa, xpbd,
// simulate and the runtime refuse; sofa wrote nan/inf for hostile radii and damping); the SOFA
// scene checked against a named list of SOFA components, their fields and the modules that
// provide them; the MuJoCo cable's numbers against the elasticity plugin's formulas.
#include <cctype>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "rodfit/model/rod.h"
#include "rodfit/model/rod_radius.h"
#include "rodfit/runtime/export.h"
#include "rodfit/runtime/export_format.h"  // internal: ExportNumbers
#include "rodfit/runtime/profile.h"

namespace rodfit {
namespace {

using ::testing::HasSubstr;
using nlohmann::json;

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

const std::string kSuture = std::string(RODFIT_SOURCE_DIR) + "/data/profiles/suture.json";

json Suture() { return json::parse(ReadText(kSuture)); }

// Exports `doc` (as "p.json") in `format`; the ProfileError's message, or "" and *text.
std::string ExportError(const json& doc, const std::string& format, std::string* text = nullptr,
                        const ProfileReadOptions& read = {}, double time_step = 0.0) {
  const std::string source = doc.dump(1);
  try {
    const Profile profile = ParseProfile(source, "p.json", read);
    ExportOptions options;
    options.time_step = time_step;
    const std::string out = Export(*FindExportFormat(format), {profile, source, options});
    if (text) *text = out;
  } catch (const ProfileError& e) {
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    return e.what();
  }
  return "";
}

TEST(ExportRegistry, EveryFormatIsOneRow) {
  std::set<std::string> names;
  for (const ExportFormat& f : ExportFormats()) {
    EXPECT_TRUE(names.insert(f.name).second) << f.name << " registered twice";
    EXPECT_NE(f.write, nullptr);
    EXPECT_GT(std::string(f.summary).size(), 10u);
    EXPECT_EQ(FindExportFormat(f.name), &f);
    EXPECT_TRUE(f.takes_time_step || !f.needs_time_step) << f.name;
  }
  EXPECT_EQ(names, (std::set<std::string>{"sofa", "mujoco", "xpbd", "json"}));
  EXPECT_EQ(FindExportFormat("obj"), nullptr);
}

TEST(ExportRegistry, OptionsAreCheckedByTheRow) {
  const std::string source = ReadText(kSuture);
  const Profile profile = ParseProfile(source, "p.json");
  ExportOptions none;
  EXPECT_THROW(Export(*FindExportFormat("xpbd"), {profile, source, none}), std::invalid_argument);
  ExportOptions step;
  step.time_step = 1e-3;
  EXPECT_THROW(Export(*FindExportFormat("json"), {profile, source, step}), std::invalid_argument);
  step.time_step = std::nan("");
  EXPECT_THROW(Export(*FindExportFormat("sofa"), {profile, source, step}), std::invalid_argument);
}

// Issue 34: `--format json`, documented as validated, accepted profiles that sofa, xpbd,
// simulate and the runtime refuse. Every format now refuses each of them, with the key.
TEST(ExportValidation, JsonRefusesWhatTheOtherFormatsRefuse) {
  struct Hostile {
    const char* what;
    std::function<void(json*)> edit;
    const char* message;
  };
  const std::vector<Hostile> cases = {
      {"stiffness 1e308", [](json* d) { (*d)["parameters"]["bend_stiffness"]["value"] = 1e308; },
       "p.json: parameters.bend_stiffness.value: 1e+308 is beyond 1e+30"},
      {"an end pin 10 m away",
       [](json* d) { (*d)["held"]["end_pin"] = {10.0, 0.0, 0.0}; },
       "p.json: the rod cannot be built: end_pin (s = 0.2) is 10 m from the clamp"},
      {"two pins on one vertex",
       [](json* d) {
         (*d)["held"]["pins"] = {{{"s", 0.1}, {"position", {0.1, 0.0, 0.0}}},
                                 {{"s", 0.1001}, {"position", {0.1, 0.0, 0.0}}}};
       },
       "p.json: "},
      {"damping 1e308", [](json* d) { (*d)["parameters"]["damping"]["value"] = 1e308; },
       "p.json: parameters.damping.value: 1e+308 is beyond 1e+30"},
  };
  for (const Hostile& h : cases) {
    json doc = Suture();
    h.edit(&doc);
    for (const char* format : {"json", "sofa", "mujoco", "xpbd"}) {
      SCOPED_TRACE(std::string(h.what) + " as " + format);
      const std::string error =
          ExportError(doc, format, nullptr, {}, std::string(format) == "xpbd" ? 1e-3 : 0.0);
      EXPECT_THAT(error, HasSubstr(h.message));
    }
  }
  // The two pins name the pins.
  json doc = Suture();
  doc["held"]["pins"] = {{{"s", 0.1}, {"position", {0.1, 0.0, 0.0}}},
                         {{"s", 0.1001}, {"position", {0.1, 0.0, 0.0}}}};
  EXPECT_THAT(ExportError(doc, "json"), HasSubstr("pins"));
}

// Issue 34: the SOFA export wrote nan/inf with exit 0 for radius 1e308 or 1e-300 and damping
// 1e308, also through --set. The radius now has a physical range wherever it is read, and every
// number written is checked.
TEST(ExportValidation, HostileRadiiAndDampingNeverReachTheFile) {
  for (double radius : {1e308, 1e-300, 5.0, 0.3}) {
    SCOPED_TRACE(radius);
    json doc = Suture();
    doc["rod"]["radius"] = radius;
    for (const char* format : {"sofa", "mujoco", "json"})
      EXPECT_THAT(ExportError(doc, format), HasSubstr("p.json: rod.radius: "));
  }
  ProfileReadOptions set;
  set.overrides["damping"] = 1e308;
  EXPECT_THAT(ExportError(Suture(), "sofa", nullptr, set),
              HasSubstr("parameters.damping.value: 1e+308 is beyond 1e+30 (--set damping)"));
  set.overrides["damping"] = 1e29;  // within the envelope, but rayleighMass = c / mu = 4.5e32:
  std::string text;                 // written, finite, and below 1e100
  EXPECT_EQ(ExportError(Suture(), "sofa", &text, set), "");
  EXPECT_THAT(text, HasSubstr("rayleighMass=\"4.46"));
  // The smallest physical radius divides: E = B / (pi r^4 / 4) ~ 1e24 Pa, still written.
  json thin = Suture();
  thin["rod"]["radius"] = kMinRodRadius;
  EXPECT_EQ(ExportError(thin, "mujoco", &text), "");
  for (const char* bad : {"nan", "inf"}) EXPECT_EQ(text.find(bad), std::string::npos);
}

TEST(ExportValidation, NumbersBeyondTheEnvelopeAreRefusedAsWritten) {
  // A quotient beyond the envelope: rayleighMass = damping / mu with a rod of 1e-300 kg/m would
  // be 1e300. Before linear_density had a physical range the writer refused it as written
  // ("export sofa: rayleighMass would be 1e+300, beyond 1e+100"); now the density itself is
  // refused before anything is derived from it, naming the key (issue 34), and the writer's check
  // below stays the backstop for every number written.
  json doc = Suture();
  doc["rod"]["linear_density"] = 1e-300;
  doc["parameters"]["damping"]["value"] = 1.0;
  const std::string error = ExportError(doc, "sofa");
  EXPECT_THAT(error, HasSubstr("p.json: "));
  EXPECT_THAT(error, HasSubstr("rod.linear_density 1e-300 kg/m is outside its physical range"));
  // The checker itself: non-finite and huge numbers, in text and in JSON documents by path.
  const Profile profile = ParseProfile(Suture().dump(), "p.json");
  const ExportNumbers num(profile, "test");
  EXPECT_EQ(num(0.25, "x"), "0.25");
  EXPECT_EQ(num(-0.0, "x"), "0");
  EXPECT_EQ(num(-1e100, "x"), "-1e+100");
  for (double bad : {std::nan(""), HUGE_VAL, -HUGE_VAL, 1.0000001e100}) {
    try {
      num(bad, "field");
      ADD_FAILURE() << bad << " written";
    } catch (const ProfileError& e) {
      EXPECT_THAT(e.what(), HasSubstr("p.json: export test: field would be"));
    }
  }
  json written = {{"a", {{"b", {1.0, 2.0, 3e200}}}}};
  try {
    num.Check(written);
    ADD_FAILURE() << "3e200 passed";
  } catch (const ProfileError& e) {
    EXPECT_THAT(e.what(), HasSubstr("a.b[2] would be 3e+200"));
  }
}

// --- SOFA -------------------------------------------------------------------------------------

// The SOFA components the scene may use, the data fields it may set on each, and the module
// (RequiredPlugin name) that provides it, as in SOFA v23.06+ (the component pages of the SOFA
// documentation and the RequiredPlugin lines of SOFA's own example scenes, e.g.
// examples/Component/SolidMechanics/FEM/BeamFEMForceField.scn). "" = part of the core.
struct SofaComponent {
  std::string module;
  std::set<std::string> fields;
};
const std::map<std::string, SofaComponent> kSofaComponents = {
    {"Node", {"", {"name", "gravity", "dt"}}},
    {"RequiredPlugin", {"", {"name"}}},
    {"DefaultAnimationLoop", {"", {}}},
    {"EulerImplicitSolver", {"Sofa.Component.ODESolver.Backward", {"rayleighStiffness", "rayleighMass"}}},
    {"SparseLDLSolver", {"Sofa.Component.LinearSolver.Direct", {}}},
    {"EdgeSetTopologyContainer", {"Sofa.Component.Topology.Container.Dynamic", {"name", "edges"}}},
    {"MechanicalObject", {"Sofa.Component.StateContainer", {"template", "name", "position", "rest_position"}}},
    {"UniformMass", {"Sofa.Component.Mass", {"totalMass"}}},
    {"BeamFEMForceField", {"Sofa.Component.SolidMechanics.FEM.Elastic",
                           {"name", "youngModulus", "poissonRatio", "radius", "radiusInner"}}},
    {"FixedProjectiveConstraint", {"Sofa.Component.Constraint.Projective", {"indices"}}},
    {"PartialFixedProjectiveConstraint", {"Sofa.Component.Constraint.Projective",
                                          {"indices", "fixedDirections"}}},
};

struct Element {
  std::string name;
  std::map<std::string, std::string> attributes;
  int depth = 0;
};

// A tag's attributes name="value" (a name: a letter or '_', then letters, digits, '_' or '.'),
// scanned by hand: libstdc++'s std::regex matcher recurses once per character of a value, and the
// SOFA export's position lists (thousands of characters) overflowed the stack of the test program
// built with AddressSanitizer, whose frames are larger.
std::map<std::string, std::string> Attributes(const std::string& tag) {
  const auto name_char = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.';
  };
  std::map<std::string, std::string> out;
  size_t at = 0;
  while ((at = tag.find("=\"", at)) != std::string::npos) {
    size_t begin = at;
    while (begin > 0 && name_char(tag[begin - 1])) --begin;
    while (begin < at && !(std::isalpha(static_cast<unsigned char>(tag[begin])) || tag[begin] == '_'))
      ++begin;
    const size_t close = tag.find('"', at + 2);
    if (close == std::string::npos) {
      ADD_FAILURE() << "unclosed attribute value in <" << tag << ">";
      break;
    }
    if (begin < at) out[tag.substr(begin, at - begin)] = tag.substr(at + 2, close - at - 2);
    at = close + 1;
  }
  return out;
}

// The elements of an XML text, comments and the declaration skipped, with their nesting depth.
std::vector<Element> Elements(const std::string& xml) {
  std::vector<Element> out;
  int depth = 0;
  size_t at = 0;
  while ((at = xml.find('<', at)) != std::string::npos) {
    if (xml.compare(at, 4, "<!--") == 0) {
      at = xml.find("-->", at);
      EXPECT_NE(at, std::string::npos) << "unclosed comment";
      continue;
    }
    const size_t end = xml.find('>', at);
    if (end == std::string::npos) break;
    const std::string tag = xml.substr(at + 1, end - at - 1);
    at = end;
    if (tag.empty() || tag[0] == '?') continue;
    if (tag[0] == '/') {
      --depth;
      continue;
    }
    Element e;
    e.name = tag.substr(0, tag.find_first_of(" \n/"));
    e.depth = depth;
    e.attributes = Attributes(tag);
    if (tag.back() != '/') ++depth;
    out.push_back(e);
  }
  EXPECT_EQ(depth, 0) << "unbalanced elements";
  return out;
}

std::vector<double> Numbers(const std::string& text) {
  std::vector<double> out;
  std::istringstream in(text);
  std::string word;
  while (in >> word) {
    size_t used = 0;
    const double v = std::stod(word, &used);
    EXPECT_EQ(used, word.size()) << word;
    out.push_back(v);
  }
  return out;
}

TEST(SofaExport, UsesOnlyNamedComponentsWithTheirModulesAndFields) {
  for (const char* name : {"suture.json", "bowel_drag.json"}) {
    SCOPED_TRACE(name);
    json doc = json::parse(ReadText(std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" + name));
    std::string text;
    ASSERT_EQ(ExportError(doc, "sofa", &text), "");
    const std::vector<Element> elements = Elements(text);
    ASSERT_FALSE(elements.empty());
    // The root: a Node with gravity and dt.
    EXPECT_EQ(elements[0].name, "Node");
    EXPECT_EQ(elements[0].depth, 0);
    EXPECT_EQ(Numbers(elements[0].attributes.at("gravity")), (std::vector<double>{0, 0, -9.81}));
    EXPECT_EQ(Numbers(elements[0].attributes.at("dt")), std::vector<double>{1e-3});
    std::set<std::string> required, used_modules;
    for (const Element& e : elements) {
      SCOPED_TRACE(e.name);
      const auto component = kSofaComponents.find(e.name);
      ASSERT_NE(component, kSofaComponents.end()) << "not in the named list";
      for (const auto& [field, value] : e.attributes) {
        EXPECT_TRUE(component->second.fields.count(field)) << field;
        if (field != "name" && field != "template") {
          for (const char* bad : {"nan", "inf"}) EXPECT_EQ(value.find(bad), std::string::npos);
        }
      }
      if (e.name == "RequiredPlugin") required.insert(e.attributes.at("name"));
      if (!component->second.module.empty()) used_modules.insert(component->second.module);
    }
    // Every module a component needs is required, and none other.
    EXPECT_EQ(required, used_modules);
    // The rod: n + 1 Rigid3d frames (7 numbers each) in position and rest_position, n edges.
    const int n = doc["rod"]["segments"].get<int>();
    for (const Element& e : elements) {
      if (e.name == "MechanicalObject") {
        EXPECT_EQ(e.attributes.at("template"), "Rigid3d");
        EXPECT_EQ(Numbers(e.attributes.at("position")).size(), 7u * (n + 1));
        EXPECT_EQ(Numbers(e.attributes.at("rest_position")).size(), 7u * (n + 1));
      }
      if (e.name == "EdgeSetTopologyContainer") {
        EXPECT_EQ(Numbers(e.attributes.at("edges")).size(), 2u * n);
      }
      if (e.name == "FixedProjectiveConstraint") {
        EXPECT_EQ(Numbers(e.attributes.at("indices")), std::vector<double>{0});
      }
      if (e.name == "BeamFEMForceField") {
        // E from the mean bending stiffness over I = pi r^4 / 4, to round-off.
        const double r = doc["rod"]["radius"].get<double>();
        const Profile p = ParseProfile(doc.dump(), "p.json");
        const double E = 0.5 * (p.scene.material.B1() + p.scene.material.B2()) /
                         (M_PI * std::pow(r, 4) / 4.0);
        EXPECT_NEAR(Numbers(e.attributes.at("youngModulus"))[0], E, 1e-12 * E);
        EXPECT_EQ(Numbers(e.attributes.at("radius"))[0], r);
      }
    }
  }
}

// --- MuJoCo -----------------------------------------------------------------------------------

TEST(MujocoExport, CableNumbersFollowTheElasticityPlugin) {
  json doc = Suture();
  doc["parameters"]["bend_damping"]["value"] = 2e-8;
  std::string text;
  ASSERT_EQ(ExportError(doc, "mujoco", &text), "");
  const Profile p = ParseProfile(doc.dump(), "p.json");
  const double r = p.scene.rod.radius, l = p.scene.rod.length / p.scene.rod.segments;
  const double I = M_PI * std::pow(r, 4) / 4.0, J = M_PI * std::pow(r, 4) / 2.0;
  const std::vector<Element> elements = Elements(text);
  std::map<std::string, std::string> config;
  const Element* composite = nullptr;
  for (const Element& e : elements) {
    if (e.name == "config") config[e.attributes.at("key")] = e.attributes.at("value");
    if (e.name == "composite") composite = &e;
    if (e.name == "option") {
      EXPECT_EQ(Numbers(e.attributes.at("gravity")), (std::vector<double>{0, 0, -9.81}));
      EXPECT_GT(Numbers(e.attributes.at("timestep"))[0], 0.0);
    }
    if (e.name == "geom") {
      EXPECT_EQ(e.attributes.at("type"), "capsule");
      EXPECT_EQ(Numbers(e.attributes.at("size"))[0], r);
      EXPECT_NEAR(Numbers(e.attributes.at("mass"))[0], p.scene.rod.linear_density * l, 1e-18);
    }
    if (e.name == "joint") {
      EXPECT_NEAR(Numbers(e.attributes.at("damping"))[0], 2e-8 / l, 1e-20);
    }
  }
  // bend = E with E I = (B1 + B2) / 2, twist = G with G J = GJ (plugin/elasticity/cable.cc).
  const double B = 0.5 * (p.scene.material.B1() + p.scene.material.B2());
  EXPECT_NEAR(std::stod(config.at("bend")) * I, B, 1e-12 * B);
  EXPECT_NEAR(std::stod(config.at("twist")) * J, p.scene.material.twist_stiffness,
              1e-12 * p.scene.material.twist_stiffness);
  EXPECT_EQ(config.at("flat"), "true");
  // The cable: a half-segment clamp body, then the rod's n + 1 vertices in the held shape.
  ASSERT_NE(composite, nullptr);
  EXPECT_EQ(composite->attributes.at("type"), "cable");
  EXPECT_EQ(composite->attributes.at("initial"), "none");
  const std::vector<double> v = Numbers(composite->attributes.at("vertex"));
  const int n = p.scene.rod.segments;
  ASSERT_EQ(v.size(), 3u * (n + 2));
  EXPECT_NEAR(v[0], -0.5 * l, 1e-15);  // the clamp at the origin along x
  EXPECT_EQ(v[3], 0.0);
  EXPECT_LT(v[3 * (n + 1) + 2], -0.01);  // the tip sags under gravity
  EXPECT_THAT(text, HasSubstr("#2208"));
  EXPECT_THAT(text, HasSubstr("stretch"));
}

TEST(MujocoExport, HeldEndsAreWeldsAndConnects) {
  json doc = Suture();
  doc["held"]["end_clamp"] = {{"position", {0.15, 0.03, -0.02}},
                              {"tangent", {1.0, 0.5, 0.0}},
                              {"normal", {0.0, 0.0, 1.0}}};
  doc["held"]["pins"] = {{{"s", 0.1}, {"position", {0.08, 0.02, -0.03}}}};
  std::string text;
  ASSERT_EQ(ExportError(doc, "mujoco", &text), "");
  // 50 segments: bodies B_first (clamp), B_1 .. B_50 (edges 0..49), B_last (the end clamp).
  EXPECT_THAT(text, HasSubstr("<weld name=\"end_clamp\" body1=\"B_last\""));
  // The pin holds vertex 25, the origin of edge 25's body, B_26.
  EXPECT_THAT(text, HasSubstr("<connect name=\"pins_0\" body1=\"B_26\" anchor=\"0 0 0\""));
  const std::vector<Element> elements = Elements(text);
  for (const Element& e : elements)
    if (e.name == "composite") {
      const std::vector<double> v = Numbers(e.attributes.at("vertex"));
      ASSERT_EQ(v.size(), 3u * 53);
      // Vertex 50 (the end clamp's) where the end clamp holds it, vertex 25 at the pin.
      EXPECT_NEAR(v[3 * 51], 0.15, 1e-9);
      EXPECT_NEAR(v[3 * 51 + 1], 0.03, 1e-9);
      EXPECT_NEAR(v[3 * 26 + 2], -0.03, 1e-9);
    }
  // An end pin: a connect at the far end of the last segment's body.
  doc["held"].erase("end_clamp");
  doc["held"]["end_pin"] = {0.18, 0.0, -0.05};
  ASSERT_EQ(ExportError(doc, "mujoco", &text), "");
  EXPECT_THAT(text, HasSubstr("<connect name=\"end_pin\" body1=\"B_last\" anchor=\"0.004"));
  // A curved rest shape with held points besides the clamp has no cable form: refused.
  doc["rod"]["rest_curvature"] = {0.0, 2.0, 0.0};
  EXPECT_THAT(ExportError(doc, "mujoco"), HasSubstr("p.json: rod.rest_curvature: "));
}

// --- The rest shape (rod.rest_shape) -------------------------------------------------------------

// The suture with a rest shape out of every plane: both bending curvatures varying along it
// (knots at 0, L/2, L), no rest twist unless asked.
json CurvedSuture(double tau = 0.0) {
  json doc = Suture();
  doc["rod"]["rest_shape"] = {{"s_m", {0.0, 0.1, 0.2}},
                              {"k1_per_m", {0.0, 5.0, 10.0}},
                              {"k2_per_m", {8.0, 8.0, 4.0}},
                              {"tau_per_m", {0.0, tau, 0.0}}};
  return doc;
}

// Every format carries the rest shape or refuses it by its key. json: the block as read. SOFA:
// rest_position is the curved rest state (its beams' reference). XPBD: rest positions and each
// joint's rest Darboux rotation, which chained from the clamp rebuild the rest positions (an
// independent check of the rotations: edge j = l_j d3 of the product). MuJoCo: a rod held at the
// clamp alone starts in its rest shape with flat=false (the plugin's reference configuration);
// with pins, or with a rest twist, refused naming rod.rest_shape.
TEST(RestShapeExport, EveryFormatCarriesItOrRefusesByKey) {
  const json doc = CurvedSuture();
  const Profile p = ParseProfile(doc.dump(), "p.json");
  const RodModel model(p.scene.rod, p.scene.material, p.scene.gravity, p.scene.cases[0]);
  ASSERT_TRUE(model.curved_at_rest());
  const RodState rest = model.RestState();
  const int n = model.num_edges();
  // The rest shape bends the suture well away from the straight line (a check that it is used).
  ASSERT_GT((rest.x.col(n) - Vec3(0.2, 0.0, 0.0)).norm(), 0.05);

  std::string text;
  ASSERT_EQ(ExportError(doc, "json", &text), "");
  EXPECT_EQ(json::parse(text)["rod"]["rest_shape"], doc["rod"]["rest_shape"]);

  ASSERT_EQ(ExportError(doc, "sofa", &text), "");
  for (const Element& e : Elements(text))
    if (e.name == "MechanicalObject") {
      const std::vector<double> r = Numbers(e.attributes.at("rest_position"));
      ASSERT_EQ(r.size(), 7u * (n + 1));
      for (int i = 0; i <= n; ++i)
        EXPECT_LT((Vec3(r[7 * i], r[7 * i + 1], r[7 * i + 2]) - rest.x.col(i)).norm(), 1e-12)
            << "vertex " << i;
    }

  ASSERT_EQ(ExportError(doc, "xpbd", &text, {}, 1e-3), "");
  const json x = json::parse(text);
  ASSERT_EQ(x["joints"].size(), static_cast<size_t>(n));
  Eigen::Quaterniond frame = [&] {
    Eigen::Matrix3d r;
    r << model.clamp_d1(), model.clamp_tangent().cross(model.clamp_d1()), model.clamp_tangent();
    return Eigen::Quaterniond(r);
  }();
  Vec3 at = model.clamp_position();
  double worst = 0.0;
  for (int i = 0; i < n; ++i) {
    const json& joint = x["joints"][i];
    const std::vector<double> q = joint["rest_rotation"].get<std::vector<double>>();
    frame = frame * Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
    at += model.rest_edge_length(i) * (frame * Vec3::UnitZ());
    const std::vector<double> p1 = x["vertices"][i + 1]["rest_position"].get<std::vector<double>>();
    worst = std::max(worst, (at - Vec3(p1[0], p1[1], p1[2])).norm());
    // The turn at a vertex of a pure bend: 2 atan(|kappa°| l_v / 2) (the tan-form curvature).
    const std::vector<double> k = joint["rest_curvature"].get<std::vector<double>>();
    const double lv = joint["voronoi_length"].get<double>();
    EXPECT_NEAR(2.0 * std::acos(std::min(1.0, q[0])), 2.0 * std::atan(std::hypot(k[0], k[1]) * lv / 2.0),
                1e-9) << "joint " << i;
  }
  EXPECT_LT(worst, 1e-12);

  json clamp_only = doc;
  clamp_only["gravity"] = {0.0, 0.0, 0.0};
  ASSERT_EQ(ExportError(clamp_only, "mujoco", &text), "");
  for (const Element& e : Elements(text)) {
    if (e.name == "config" && e.attributes.at("key") == "flat") {
      EXPECT_EQ(e.attributes.at("value"), "false");
    }
    if (e.name == "composite") {
      const std::vector<double> v = Numbers(e.attributes.at("vertex"));
      ASSERT_EQ(v.size(), 3u * (n + 2));  // the clamp's half segment, then the n + 1 vertices
      for (int i = 0; i <= n; ++i)
        EXPECT_LT((Vec3(v[3 * (i + 1)], v[3 * (i + 1) + 1], v[3 * (i + 1) + 2]) - rest.x.col(i)).norm(),
                  1e-12);
    }
  }
  json pinned = doc;
  pinned["held"]["pins"] = {{{"s", 0.1}, {"position", {0.05, 0.05, 0.0}}}};
  EXPECT_THAT(ExportError(pinned, "mujoco"),
              HasSubstr("p.json: rod.rest_shape: a curved rest shape with held points besides "
                        "the clamp"));
  EXPECT_THAT(ExportError(CurvedSuture(2.0), "mujoco"),
              HasSubstr("p.json: rod.rest_shape.tau_per_m: a rest twist has no MJCF cable"));
}

}  // namespace
}  // namespace rodfit
