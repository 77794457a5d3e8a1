// `rodfit simulate --profile` and `rodfit export`: a fitted profile drives the same solve as the
// scene it came from, the runtime ends a drag in the equilibrium `simulate` writes, and every
// mistake is one line on stderr with nothing written.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/run_cli.h"
#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"

namespace rodfit {
namespace {

using ::testing::HasSubstr;
using test::Quote;
using test::RunRodfit;
using test::TempDir;

const std::string kSource = RODFIT_SOURCE_DIR;
const std::string kDragScene = kSource + "/calibration/tissue_drag/experiment.yaml";
const std::string kDragProfile = kSource + "/data/profiles/bowel_drag.json";

// shapes.csv rows of one case: vertex -> (x, y, z).
std::map<int, Vec3> CaseShape(const std::string& csv, const std::string& name) {
  std::map<int, Vec3> out;
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);  // case,vertex,s,x,y,z
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string c, vertex, s, x, y, z;
    std::getline(row, c, ',');
    std::getline(row, vertex, ',');
    std::getline(row, s, ',');
    std::getline(row, x, ',');
    std::getline(row, y, ',');
    std::getline(row, z, ',');
    if (c == name) out[std::stoi(vertex)] = Vec3(std::stod(x), std::stod(y), std::stod(z));
  }
  return out;
}

// The profile's rod and held ends, the recipe's drag case, the fitted springs: the runtime
// dragged to the case's grasp ends where `simulate --profile` puts the rod, to 1e-10 L.
TEST(RuntimeCli, SimulateWithProfileIsTheRuntimesEquilibrium) {
  TempDir dir;
  const test::RunResult run =
      RunRodfit(dir, "simulate " + Quote(kDragScene) + " --profile " + Quote(kDragProfile) +
                         " -o " + Quote(dir.File("out")));
  ASSERT_EQ(run.status, 0) << run.err;
  const std::map<int, Vec3> simulated = CaseShape(test::ReadText(dir.File("out/shapes.csv")), "drag");
  ASSERT_FALSE(simulated.empty());

  RuntimeOptions options;
  options.tool_s = 0.1;  // the recipe's grasp
  Runtime rt(LoadProfile(kDragProfile), options);
  const Vec3 target(0.1, 0.015, 0.02), from = rt.ToolPosition();
  const int ticks = 200;
  for (int k = 1; k <= ticks; ++k) {
    rt.SetToolPosition(from + (target - from) * (static_cast<double>(k) / ticks));
    StepReport r = rt.Step();
    for (int extra = 0; r.ok() && r.tool_lag > 0.0 && extra < 100; ++extra) r = rt.Step();
    ASSERT_TRUE(r.ok()) << "tick " << k;
  }
  ASSERT_EQ(static_cast<int>(simulated.size()), rt.model().num_vertices());
  double error = 0.0;
  for (const auto& [i, x] : simulated) error = std::max(error, (rt.Shape().col(i) - x).cwiseAbs().maxCoeff());
  std::printf("runtime vs simulate --profile: max |dx| = %.3e m\n", error);
  // shapes.csv holds 17 significant digits: the comparison is the solves', not the text's.
  EXPECT_LT(error, 1e-10 * rt.model().length());
}

// A scene without parameters: the profile supplies them, and the results are those of the
// recipe's own file with the profile's values.
TEST(RuntimeCli, SceneWithoutParametersTakesTheProfiles) {
  TempDir dir;
  std::string scene = test::ReadText(kDragScene);
  const size_t from = scene.find("parameters:"), to = scene.find("gravity:");
  ASSERT_NE(from, std::string::npos);
  scene.erase(from, to - from);
  const std::string bare = dir.Write("bare.yaml", scene);
  const test::RunResult a =
      RunRodfit(dir, "simulate " + Quote(bare) + " --profile " + Quote(kDragProfile) + " -o " +
                         Quote(dir.File("a")));
  ASSERT_EQ(a.status, 0) << a.err;
  const test::RunResult b =
      RunRodfit(dir, "simulate " + Quote(kDragScene) + " --profile " + Quote(kDragProfile) +
                         " -o " + Quote(dir.File("b")));
  ASSERT_EQ(b.status, 0) << b.err;
  EXPECT_EQ(test::ReadText(dir.File("a/shapes.csv")), test::ReadText(dir.File("b/shapes.csv")));
  EXPECT_EQ(test::ReadText(dir.File("a/forces.csv")), test::ReadText(dir.File("b/forces.csv")));
  // Without --profile the scene needs its parameters.
  const test::RunResult c = RunRodfit(dir, "simulate " + Quote(bare) + " -o " + Quote(dir.File("c")));
  EXPECT_EQ(c.status, 1);
  EXPECT_THAT(c.err, HasSubstr("parameters: missing"));
}

TEST(RuntimeCli, ProfileMistakesAreOneLineAndWriteNothing) {
  TempDir dir;
  nlohmann::json doc = nlohmann::json::parse(test::ReadText(kDragProfile));
  struct Case {
    std::function<void(nlohmann::json*)> edit;
    std::string extra, message;
  };
  const std::vector<Case> cases = {
      {[](nlohmann::json* d) { (*d)["rod"]["segments"] = 41; }, "",
       "p.json: rod.segments: 41 differs from the scene's 40"},
      {[](nlohmann::json* d) { (*d)["parameters"]["mesentery"]["unit"] = "N/m"; }, "",
       "p.json: parameters.mesentery.unit: must be \"N/m^2\""},
      {[](nlohmann::json* d) {
         (*d)["parameters"]["mesentery"]["value"] = nullptr;
         (*d)["parameters"]["mesentery"]["identifiable"] = false;
       },
       "", "p.json: parameters.mesentery.value: is null"},
      {[](nlohmann::json* d) { (*d)["version"] = 7; }, "", "p.json: version: 7 is not supported"},
      {[](nlohmann::json*) {}, "--set mesentery=abc", "--set mesentery: \"abc\" is not a finite number"},
      {[](nlohmann::json*) {}, "--set nothing=1", "p.json: parameters.nothing: --set names"},
  };
  for (const Case& c : cases) {
    nlohmann::json edited = doc;
    c.edit(&edited);
    dir.Write("p.json", edited.dump(2));
    const test::RunResult run =
        RunRodfit(dir, "simulate " + Quote(kDragScene) + " --profile " + Quote(dir.File("p.json")) + " " + c.extra + " -o " +
                           Quote(dir.File("out")));
    EXPECT_EQ(run.status, 1) << c.message;
    EXPECT_THAT(run.err, HasSubstr(c.message));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    EXPECT_FALSE(std::filesystem::exists(dir.File("out"))) << c.message;
  }
  // An undetermined parameter with a value given: solved.
  nlohmann::json undetermined = doc;
  undetermined["parameters"]["mesentery"]["value"] = nullptr;
  undetermined["parameters"]["mesentery"]["identifiable"] = false;
  dir.Write("u.json", undetermined.dump(2));
  const test::RunResult run = RunRodfit(
      dir, "simulate " + Quote(kDragScene) + " --profile " + Quote(dir.File("u.json")) +
               " --set mesentery=400 -o " + Quote(dir.File("set")));
  EXPECT_EQ(run.status, 0) << run.err;
}

TEST(RuntimeCli, ExportWritesEachFormat) {
  TempDir dir;
  const std::string suture = kSource + "/data/profiles/suture.json";
  ASSERT_EQ(RunRodfit(dir, "export " + Quote(suture) + " --format json -o " + Quote(dir.File("p.json"))).status, 0);
  // The json export reads back to the same rod and material.
  const Profile original = LoadProfile(suture), exported = LoadProfile(dir.File("p.json"));
  EXPECT_EQ(exported.scene.material.B1(), original.scene.material.B1());
  EXPECT_EQ(exported.scene.material.B2(), original.scene.material.B2());
  EXPECT_EQ(exported.scene.rod.segments, original.scene.rod.segments);

  ASSERT_EQ(RunRodfit(dir, "export " + Quote(suture) + " --format xpbd --time-step 0.002 -o " +
                               Quote(dir.File("x.json"))).status, 0);
  const nlohmann::json x = nlohmann::json::parse(test::ReadText(dir.File("x.json")));
  const double ea = original.scene.material.stretch_stiffness;
  ASSERT_EQ(x["segments"].size(), static_cast<size_t>(original.scene.rod.segments));
  const double l = x["segments"][3]["rest_length"].get<double>();
  EXPECT_DOUBLE_EQ(x["segments"][3]["stretch_compliance"].get<double>(), l / ea);
  EXPECT_DOUBLE_EQ(x["segments"][3]["stretch_compliance_dt"].get<double>(), l / ea / 4e-6);
  const double lv = x["joints"][5]["voronoi_length"].get<double>();
  EXPECT_DOUBLE_EQ(x["joints"][5]["bend_2_compliance"].get<double>(), lv / original.scene.material.B2());

  ASSERT_EQ(RunRodfit(dir, "export " + Quote(suture) + " --format sofa -o " + Quote(dir.File("s.xml"))).status, 0);
  const std::string sofa = test::ReadText(dir.File("s.xml"));
  for (const char* name : {"youngModulus=", "poissonRatio=", "radius=", "massDensity=",
                           "rayleighStiffness=", "rayleighMass=", "BeamFEMForceField",
                           "BeamHookeLawForceField"})
    EXPECT_THAT(sofa, HasSubstr(name));
  // An XML comment may not hold "--".
  size_t at = 0;
  while ((at = sofa.find("<!--", at)) != std::string::npos) {
    const size_t end = sofa.find("-->", at + 4);
    ASSERT_NE(end, std::string::npos);
    EXPECT_EQ(sofa.substr(at + 4, end - at - 4).find("--"), std::string::npos);
    at = end;
  }
}

// A profile whose rod is held at both ends (a wire between two clamps, with a pin): the exports
// hold every held vertex where its holder holds it, not only the clamp, and start the rod in the
// held shape. The suture profile with an end clamp 0.15 m from the clamp, out of its plane.
TEST(RuntimeCli, ExportHoldsEveryHeldPointWhereItsHolderHoldsIt) {
  TempDir dir;
  nlohmann::json profile = nlohmann::json::parse(test::ReadText(kSource + "/data/profiles/suture.json"));
  profile["held"]["end_clamp"] = {{"position", {0.15, 0.03, -0.02}},
                                  {"tangent", {1.0, 0.5, 0.0}},
                                  {"normal", {0.0, 0.0, 1.0}}};
  profile["held"]["pins"] = {{{"s", 0.1}, {"position", {0.08, 0.02, -0.03}}}};
  const std::string path = dir.Write("two_clamps.json", profile.dump(1));
  ASSERT_EQ(RunRodfit(dir, "export " + Quote(path) + " --format xpbd --time-step 0.002 -o " +
                               Quote(dir.File("x.json"))).status, 0);
  const nlohmann::json x = nlohmann::json::parse(test::ReadText(dir.File("x.json")));
  const nlohmann::json& v = x["vertices"];
  const int n = profile["rod"]["segments"].get<int>();
  ASSERT_EQ(v.size(), static_cast<size_t>(n + 1));
  auto at = [](const nlohmann::json& a) { return Vec3(a[0], a[1], a[2]); };
  // The end clamp's vertex: fixed where the end clamp is, with its frame; the rest shape's tip
  // (the straight rod, 0.2 m along x) is elsewhere.
  EXPECT_EQ(v[n]["fixed"], true);
  EXPECT_EQ(v[n]["held_by"], "end_clamp");
  EXPECT_LT((at(v[n]["start_position"]) - Vec3(0.15, 0.03, -0.02)).norm(), 1e-9);
  EXPECT_GT((at(v[n]["rest_position"]) - Vec3(0.15, 0.03, -0.02)).norm(), 0.04);
  EXPECT_LT((at(v[n]["held_frame"]["tangent"]) - Vec3(1, 0.5, 0).normalized()).norm(), 1e-12);
  // The pin at s = 0.1 m (vertex 25 of 50): fixed at its position, no frame.
  EXPECT_EQ(v[25]["held_by"], "pins[0]");
  EXPECT_LT((at(v[25]["start_position"]) - Vec3(0.08, 0.02, -0.03)).norm(), 1e-9);
  EXPECT_FALSE(v[25].contains("held_frame"));
  EXPECT_EQ(v[0]["held_by"], "clamp");
  int fixed = 0;
  for (const auto& vertex : v) fixed += vertex["fixed"].get<bool>() ? 1 : 0;
  EXPECT_EQ(fixed, 3);
  // The start shape is the held equilibrium: consecutive vertices a rest length apart (to the
  // stretch of a suture under its own weight), not stretched to reach the holders.
  for (int i = 0; i < n; ++i)
    EXPECT_NEAR((at(v[i + 1]["start_position"]) - at(v[i]["start_position"])).norm(),
                x["segments"][i]["rest_length"].get<double>(), 1e-6);

  ASSERT_EQ(RunRodfit(dir, "export " + Quote(path) + " --format sofa -o " + Quote(dir.File("s.xml"))).status, 0);
  const std::string sofa = test::ReadText(dir.File("s.xml"));
  // SOFA v23.06 renamed FixedConstraint and PartialFixedConstraint to these (the scene loads in
  // current SOFA releases).
  EXPECT_THAT(sofa, HasSubstr("<FixedProjectiveConstraint indices=\"0 " + std::to_string(n) +
                              "\"/>  <!-- clamp, end_clamp -->"));
  EXPECT_THAT(sofa, HasSubstr("<PartialFixedProjectiveConstraint indices=\"25\" fixedDirections=\"1 1 1 0 0 0\"/>"));
  EXPECT_THAT(sofa, HasSubstr("rest_position=\""));
  // The last vertex of `position` is the end clamp: "0.14999999999999999 0.029999999999999999".
  const size_t pos = sofa.find("position=\""), rest = sofa.find("rest_position=\"");
  ASSERT_NE(pos, std::string::npos);
  const std::string positions = sofa.substr(pos, rest - pos);
  EXPECT_THAT(positions, HasSubstr("0.14999999999999999 0.029999999999999999 -0.02"));
}

TEST(RuntimeCli, ExportMistakesWriteNothing) {
  TempDir dir;
  const std::string suture = kSource + "/data/profiles/suture.json";
  test::RunResult run =
      RunRodfit(dir, "export " + Quote(suture) + " --format xpbd -o " + Quote(dir.File("x.json")));
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("needs --time-step"));
  nlohmann::json doc = nlohmann::json::parse(test::ReadText(suture));
  doc["parameters"]["bend_stiffness"]["value"] = -1.0;
  dir.Write("bad.json", doc.dump());
  run = RunRodfit(dir, "export " + Quote(dir.File("bad.json")) + " --format sofa -o " +
                          Quote(dir.File("s.xml")));
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("bad.json: parameters.bend_stiffness.value: must be > 0"));
  EXPECT_FALSE(std::filesystem::exists(dir.File("s.xml")));
  run = RunRodfit(dir, "export " + Quote(dir.File("bad.json")) + " --format json -o " +
                          Quote(dir.File("bad.json")));
  EXPECT_EQ(run.status, 1);
  EXPECT_EQ(test::ReadText(dir.File("bad.json")), doc.dump());  // never over its input
}

}  // namespace
}  // namespace rodfit
