// The validating profile reader (rodfit/runtime/profile.h): the bundled fitted profiles read
// back into the rod they describe, and every kind of mistake fails with one line naming the
// file and the JSON key.
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "rodfit/model/material_parameters.h"
#include "rodfit/runtime/profile.h"

namespace rodfit {
namespace {

using ::testing::HasSubstr;
using nlohmann::json;

std::string ProfilePath(const std::string& name) {
  return std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" + name;
}

json ReadJson(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return json::parse(text.str());
}

// The message of the ProfileError that parsing `doc` throws ("" when none).
std::string ErrorOf(const json& doc, const ProfileReadOptions& options = {}) {
  try {
    ParseProfile(doc.dump(), "p.json", options);
  } catch (const ProfileError& e) {
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    return e.what();
  }
  return "";
}

TEST(ProfileReader, BundledProfilesRebuildTheirRods) {
  for (const char* name : {"suture.json", "bowel_drag.json", "bowel_poke.json"}) {
    SCOPED_TRACE(name);
    const json doc = ReadJson(ProfilePath(name));
    const Profile p = LoadProfile(ProfilePath(name));
    EXPECT_EQ(p.version, 2);
    EXPECT_EQ(p.scene.rod.length, doc["rod"]["length"].get<double>());
    EXPECT_EQ(p.scene.rod.segments, doc["rod"]["segments"].get<int>());
    EXPECT_EQ(p.scene.rod.radius, doc["rod"]["radius"].get<double>());
    ASSERT_EQ(p.scene.cases.size(), 1u);
    EXPECT_EQ(p.scene.springs.size(), doc["springs"].size());
    EXPECT_EQ(p.scene.section.has_value(), doc.contains("section"));
    // Every parameter's value is the profile's, to the bit, in the material the rod reads.
    for (const auto& item : doc["parameters"].items()) {
      if (item.value().contains("tied_to")) continue;
      const std::optional<double> v = MaterialParameterValue(p.scene.material, item.key());
      ASSERT_TRUE(v.has_value()) << item.key();
      EXPECT_EQ(*v, item.value()["value"].get<double>()) << item.key();
    }
  }
}

TEST(ProfileReader, DerivedConstantsFollowFromTheStiffnesses) {
  const json doc = ReadJson(ProfilePath("suture.json"));
  const json& round = doc["derived"]["round_section"];
  const double r = doc["rod"]["radius"].get<double>();
  const double b1 = doc["parameters"]["bend_stiffness"]["value"].get<double>();
  const double b2 = doc["parameters"]["bend_stiffness_2"]["value"].get<double>();
  const double gj = doc["parameters"]["twist_stiffness"]["value"].get<double>();
  const double i = M_PI * std::pow(r, 4) / 4.0;
  EXPECT_NEAR(round["youngs_modulus"].get<double>(), 0.5 * (b1 + b2) / i, 1e-12 * (b1 / i));
  EXPECT_NEAR(round["shear_modulus"].get<double>(), gj / (2.0 * i), 1e-12 * gj / i);
  const double e = round["youngs_modulus"].get<double>(), g = round["shear_modulus"].get<double>();
  EXPECT_NEAR(round["poisson_ratio"].get<double>(), e / (2.0 * g) - 1.0, 1e-12);
  // The bowel is a soft tube, not a solid round section of one material: flagged.
  const json bowel = ReadJson(ProfilePath("bowel_drag.json"));
  EXPECT_FALSE(bowel["derived"]["round_section"]["consistent"].get<bool>());
  EXPECT_FALSE(bowel["derived"]["round_section"]["inconsistency"].get<std::string>().empty());
}

TEST(ProfileReader, VersionOneStillReads) {
  json doc = ReadJson(ProfilePath("suture.json"));
  doc["version"] = 1;
  for (const char* key : {"held", "springs", "section", "derived"}) doc.erase(key);
  const Profile p = ParseProfile(doc.dump(), "v1.json");
  EXPECT_EQ(p.version, 1);
  EXPECT_EQ(p.scene.material.bend_stiffness,
            doc["parameters"]["bend_stiffness"]["value"].get<double>());
}

TEST(ProfileReader, MistakesNameTheFileAndKey) {
  const json good = ReadJson(ProfilePath("suture.json"));
  ASSERT_EQ(ErrorOf(good), "");
  struct Case {
    std::function<void(json*)> edit;
    std::string message;
  };
  const std::vector<Case> cases = {
      {[](json* d) { (*d)["format"] = "other"; }, "p.json: format: must be \"rodfit-profile\""},
      {[](json* d) { (*d)["version"] = 3; }, "p.json: version: 3 is not supported"},
      {[](json* d) { (*d)["parameters"]["bend_stiffness"]["value"] = -1.0; },
       "p.json: parameters.bend_stiffness.value: must be > 0"},
      {[](json* d) { (*d)["parameters"]["bend_stiffness"]["unit"] = "N m"; },
       "p.json: parameters.bend_stiffness.unit: must be \"N m^2\""},
      {[](json* d) { (*d)["parameters"]["twist_stiffness"]["value"] = "1e-6"; },
       "p.json: parameters.twist_stiffness.value: must be a number"},
      {[](json* d) { (*d)["parameters"].erase("stretch_stiffness"); },
       "p.json: parameters.stretch_stiffness: missing"},
      {[](json* d) { (*d)["rod"]["segments"] = 1; }, "p.json: rod.segments: must be in [2, "},
      {[](json* d) { (*d)["rod"]["length"] = 0.0; }, "p.json: rod.length: must be > 0"},
      {[](json* d) { (*d)["rod"].erase("length"); }, "p.json: rod.length: missing"},
      {[](json* d) { (*d)["gravity"] = json::array({0, 0}); }, "p.json: gravity: must be an array"},
      {[](json* d) { (*d)["held"]["clamp"]["normal"] = json::array({1, 0, 0}); },
       "p.json: held.clamp.normal: is (nearly) parallel to the tangent"},
      {[](json* d) { (*d)["held"]["cuts"] = json::array({{{"from", 0.1}, {"to", 0.05}}}); },
       "p.json: held.cuts[0].to: must be greater than from"},
      {[](json* d) { (*d)["parameters"]["bend_stiffness"]["bogus"] = 1; },
       "p.json: parameters.bend_stiffness.bogus: unknown key"},
      {[](json* d) { (*d)["parameters"]["made_up"] = (*d)["parameters"]["bend_stiffness"]; },
       "p.json: parameters.made_up: unknown parameter"},
  };
  for (const Case& c : cases) {
    json doc = good;
    c.edit(&doc);
    EXPECT_THAT(ErrorOf(doc), HasSubstr(c.message));
  }
  EXPECT_THAT(ErrorOf(json::parse("[1, 2]")), HasSubstr("p.json: must be an object"));
  EXPECT_THAT(ErrorOf(json::parse("{}")), HasSubstr("p.json: format: missing"));
  try {
    ParseProfile("{not json", "p.json");
    ADD_FAILURE() << "no error";
  } catch (const ProfileError& e) {
    EXPECT_THAT(e.what(), HasSubstr("p.json: not a JSON document"));
  }
  try {
    LoadProfile(ProfilePath("no_such_profile.json"));
    ADD_FAILURE() << "no error";
  } catch (const ProfileError& e) {
    EXPECT_THAT(e.what(), HasSubstr("no_such_profile.json: cannot read the file"));
  }
}

TEST(ProfileReader, UndeterminedParameterNeedsAnOverride) {
  json doc = ReadJson(ProfilePath("suture.json"));
  json& b2 = doc["parameters"]["bend_stiffness_2"];
  b2["value"] = nullptr;
  b2["std"] = nullptr;
  b2["identifiable"] = false;
  b2["reason"] = "not separable from bend_stiffness";
  EXPECT_THAT(ErrorOf(doc), HasSubstr("p.json: parameters.bend_stiffness_2.value: is null (not "
                                      "identifiable by the fit); rodfit does not invent one: "
                                      "give it with --set bend_stiffness_2=VALUE"));
  ProfileReadOptions options;
  options.overrides["bend_stiffness_2"] = 2.5e-6;
  const Profile p = ParseProfile(doc.dump(), "p.json", options);
  EXPECT_EQ(p.scene.material.B2(), 2.5e-6);
  EXPECT_TRUE(p.Find("bend_stiffness_2")->overridden);
  // An override is checked like a value, and must name a listed parameter.
  options.overrides["bend_stiffness_2"] = -1.0;
  EXPECT_THAT(ErrorOf(doc, options),
              HasSubstr("parameters.bend_stiffness_2.value (--set bend_stiffness_2): must be > 0"));
  options.overrides = {{"bend_stifness", 1.0}};
  EXPECT_THAT(ErrorOf(ReadJson(ProfilePath("suture.json")), options), HasSubstr("parameters.bend_stifness: --set names"));
}

// A moving fit may list the rod's linear density it fitted (docs/formats.md, profile
// "parameters"): the row sets the rebuilt rod's masses, must agree with rod.linear_density, is
// positive and in kg/m, and --set replaces both.
// Every row of the parameter table has a physical range, finite and positive, that its own
// bundled values lie in; 0 is taken only for a row that may be 0 (the term off).
TEST(ProfileReader, EveryParameterRowHasAPhysicalRange) {
  for (const MaterialParameterInfo& row : MaterialParameters()) {
    SCOPED_TRACE(row.name);
    EXPECT_GT(row.lowest, 0.0);
    EXPECT_LT(row.lowest, row.highest);
    EXPECT_TRUE(std::isfinite(row.highest));
    EXPECT_EQ(CheckMaterialParameterRange(row, row.lowest), "");
    EXPECT_EQ(CheckMaterialParameterRange(row, row.highest), "");
    EXPECT_NE(CheckMaterialParameterRange(row, 0.5 * row.lowest), "");
    EXPECT_NE(CheckMaterialParameterRange(row, 2.0 * row.highest), "");
    EXPECT_NE(CheckMaterialParameterRange(row, std::nan("")), "");
    EXPECT_EQ(CheckMaterialParameterRange(row, 0.0).empty(), !row.positive);
  }
  for (const char* name : {"suture.json", "bowel_drag.json", "bowel_poke.json"}) {
    const Profile p = LoadProfile(ProfilePath(name));
    for (const Parameter& parameter : p.parameters)
      if (const MaterialParameterInfo* row = FindMaterialParameter(parameter.name))
        EXPECT_EQ(CheckMaterialParameterRange(*row, parameter.value), "") << parameter.name;
    const MaterialParameterInfo* density = FindMaterialParameter("linear_density");
    ASSERT_NE(density, nullptr);
    EXPECT_EQ(CheckMaterialParameterRange(*density, p.scene.rod.linear_density), "");
  }
}

TEST(ProfileReader, AFittedLinearDensitySetsTheRod) {
  json doc = ReadJson(ProfilePath("suture.json"));
  const double density = doc["rod"]["linear_density"].get<double>();
  doc["parameters"]["linear_density"] = {{"value", density}, {"std", 0.01 * density},
                                         {"unit", "kg/m"},   {"fitted", true},
                                         {"identifiable", true}};
  EXPECT_EQ(ParseProfile(doc.dump(), "p.json").scene.rod.linear_density, density);
  ProfileReadOptions options;
  options.overrides["linear_density"] = 2.0 * density;
  const Profile set = ParseProfile(doc.dump(), "p.json", options);
  EXPECT_EQ(set.scene.rod.linear_density, 2.0 * density);
  json wrong = doc;
  wrong["parameters"]["linear_density"]["value"] = 1.5 * density;
  EXPECT_THAT(ErrorOf(wrong), HasSubstr("p.json: parameters.linear_density.value: disagrees with "
                                        "rod.linear_density"));
  wrong = doc;
  wrong["parameters"]["linear_density"]["unit"] = "kg/m^3";
  EXPECT_THAT(ErrorOf(wrong), HasSubstr("parameters.linear_density.unit: must be \"kg/m\""));
  wrong = doc;
  wrong["parameters"]["linear_density"]["value"] = 0.0;
  wrong["rod"]["linear_density"] = 0.0;
  EXPECT_THAT(ErrorOf(wrong), HasSubstr("parameters.linear_density.value: must be > 0"));
  // Outside its physical range [1e-15, 1e5] kg/m: refused on read and on --set, naming the key.
  wrong = doc;
  wrong["parameters"]["linear_density"]["value"] = 1e-300;
  wrong["rod"]["linear_density"] = 1e-300;
  EXPECT_THAT(ErrorOf(wrong), HasSubstr("p.json: parameters.linear_density.value: 1e-300 is below "
                                        "1e-15, outside linear_density's physical range"));
  ProfileReadOptions tiny;
  tiny.overrides["linear_density"] = 1e-300;
  EXPECT_THAT(ErrorOf(doc, tiny),
              HasSubstr("parameters.linear_density.value: 1e-300 is below 1e-15 (--set "
                        "linear_density)"));
  // A scene read for a profile (parameters optional) may leave its density out: the profile's.
  const Profile p = ParseProfile(doc.dump(), "p.json");
  Scene scene = p.scene;
  scene.rod.linear_density = std::numeric_limits<double>::quiet_NaN();
  UseProfileMaterial(p, &scene);
  EXPECT_EQ(scene.rod.linear_density, density);
  scene.rod.linear_density = 0.5 * density;
  try {
    UseProfileMaterial(p, &scene);
    ADD_FAILURE() << "a scene with another density was accepted";
  } catch (const ProfileError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("rod.linear_density:"));
  }
}

// rod.rest_shape: the knots of the rod's natural shape read into the rod, each list checked
// (finite, one entry per knot, arc lengths increasing within the rod, a turn per segment the
// discrete rod can hold), every mistake named by its key.
TEST(ProfileReader, RestShapeIsReadAndChecked) {
  json doc = ReadJson(ProfilePath("suture.json"));
  const double length = doc["rod"]["length"].get<double>();
  doc["rod"]["rest_shape"] = {{"s_m", {0.0, 0.5 * length, length}},
                              {"k1_per_m", {1.0, 2.0, 3.0}},
                              {"k2_per_m", {-1.0, 0.0, 0.5}},
                              {"tau_per_m", {0.0, 0.0, 0.25}}};
  const Profile p = ParseProfile(doc.dump(), "p.json");
  ASSERT_EQ(p.scene.rod.rest_curvature_s.size(), 3u);
  EXPECT_EQ(p.scene.rod.rest_curvature_s[1], 0.5 * length);
  ASSERT_EQ(p.scene.rod.rest_curvature_profile.size(), 3u);
  EXPECT_EQ(p.scene.rod.rest_curvature_profile[0], Vec3(1.0, -1.0, 0.0));
  EXPECT_EQ(p.scene.rod.rest_curvature_profile[2], Vec3(3.0, 0.5, 0.25));
  // A profile without one: a rod without one.
  EXPECT_TRUE(LoadProfile(ProfilePath("suture.json")).scene.rod.rest_curvature_s.empty());

  auto error = [&](const std::function<void(json&)>& edit) {
    json wrong = doc;
    edit(wrong["rod"]["rest_shape"]);
    return ErrorOf(wrong);
  };
  EXPECT_THAT(error([](json& r) { r["k1_per_m"] = {1.0, 2.0}; }),
              HasSubstr("p.json: rod.rest_shape.k1_per_m: must have one entry per knot of s_m (3"));
  EXPECT_THAT(error([](json& r) { r.erase("tau_per_m"); }),
              HasSubstr("p.json: rod.rest_shape.tau_per_m: must have one entry per knot"));
  EXPECT_THAT(error([](json& r) { r["k2_per_m"][1] = "x"; }),
              HasSubstr("p.json: rod.rest_shape.k2_per_m[1]: must be a number"));
  EXPECT_THAT(error([](json& r) { r["s_m"][1] = 0.0; }),
              HasSubstr("p.json: rod.rest_shape.s_m[1]: must increase strictly"));
  EXPECT_THAT(error([length](json& r) { r["s_m"][2] = 1.5 * length; }),
              HasSubstr("p.json: rod.rest_shape.s_m[2]: must lie in [0, rod.length"));
  EXPECT_THAT(error([](json& r) { r["s_m"] = json::array(); }),
              HasSubstr("p.json: rod.rest_shape.s_m: must list the knots"));
  // 1e5 1/m over a segment of 4 mm: a turn of 400 per segment, refused.
  EXPECT_THAT(error([](json& r) { r["k1_per_m"][2] = 1e5; }),
              HasSubstr("p.json: rod.rest_shape.k1_per_m[2]: the rest curvature at this knot "
                        "turns the rod by"));
  EXPECT_THAT(error([](json& r) { r["bend"] = 1.0; }),
              HasSubstr("p.json: rod.rest_shape.bend: unknown key"));
  // `simulate SCENE --profile P`: a scene without a rest shape takes the profile's; a scene with
  // another one is refused, naming the key.
  Scene scene = LoadProfile(ProfilePath("suture.json")).scene;
  UseProfileMaterial(p, &scene);
  EXPECT_EQ(scene.rod.rest_curvature_s, p.scene.rod.rest_curvature_s);
  EXPECT_EQ(scene.rod.rest_curvature_profile, p.scene.rod.rest_curvature_profile);
  UseProfileMaterial(p, &scene);  // the same one again: accepted
  scene.rod.rest_curvature_profile[1][0] += 0.5;
  try {
    UseProfileMaterial(p, &scene);
    ADD_FAILURE() << "a scene with another rest shape was accepted";
  } catch (const ProfileError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("p.json: rod.rest_shape: differs from the scene's"));
  }
  // A NaN is written as null by JSON: not a number.
  EXPECT_THAT(error([](json& r) { r["tau_per_m"][0] = std::nan(""); }),
              HasSubstr("p.json: rod.rest_shape.tau_per_m[0]: must be a number"));
}

}  // namespace
}  // namespace rodfit
