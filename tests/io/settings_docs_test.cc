// The settings' one declaration (rodfit/model/settings_archive.h) against their documentation:
// every key that Serialize declares for `solver:`, `fit:` and `dynamics:` has its row in
// docs/formats.md's table, and every key of the rollout's and the motion fit's in docs/cli.md's
// ("rollout", "Settings"), and that row states the key's range and its default as the structs
// declare them (or that it is required) — and in docs/cli.md its command-line option, or `—` —
// so that neither can change without the other, and a setting added without its row fails here.
#include "rodfit/io/settings.h"

#include <limits>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "settings_docs.h"
#include "rodfit/fit/motion_fit.h"
#include "rodfit/solve/integrator.h"
#include "rodfit/solve/rollout.h"

namespace rodfit {
namespace {

using test::DocsArchive;
using test::kCliDoc;
using test::RowKeys;

TEST(SettingsDocs, EveryKeyHasItsRangeAndDefaultInTheDocs) {
  StaticsOptions statics;
  DocsArchive solver("solver");
  Serialize(&solver, &statics);
  FitOptions fit;
  DocsArchive fitting("fit");
  Serialize(&fitting, &fit);
  DynamicsSpec dynamics;
  DocsArchive moving("dynamics");
  Serialize(&moving, &dynamics, IntegratorNames());
  // The numeric keys were all visited (a Serialize that declares none would pass vacuously).
  EXPECT_EQ(solver.keys(), 3);
  EXPECT_EQ(fitting.keys(), 1);
  EXPECT_EQ(moving.keys(), 6);
}

// The fit settings a profile carries (SettingsArchive::Carry in Serialize(FitOptions)): each is
// a setting the `fit:` block declares and is shown in docs/formats.md's profile, as written.
TEST(SettingsDocs, TheProfilesCarriedFitSettingsAreDeclaredAndDocumented) {
  class Carried final : public SettingsArchive {
   public:
    std::vector<std::pair<std::string, std::string>> carried;  // key, profile key
    std::set<std::string> visited;
    bool reading() const override { return false; }
    void Carry(const char* key, const char* profile_key) override {
      carried.emplace_back(key, profile_key);
    }
    void Integer(const char* key, int*, int, int) override { visited.insert(key); }
    void Count(const char* key, int*, int, int) override { visited.insert(key); }
    void Number(const char* key, double*, double, double) override { visited.insert(key); }
    void Positive(const char* key, double*) override { visited.insert(key); }
    void Bool(const char* key, bool*) override { visited.insert(key); }
    void Choice(const char* key, int*, const std::vector<std::string>&,
                const std::string&) override {
      visited.insert(key);
    }
    void Require(const char*) override {}
    bool Has(const char*) const override { return false; }
    void Check(bool, const char*, const std::string&) override {}
  } archive;
  FitOptions fit;
  Serialize(&archive, &fit);
  ASSERT_EQ(archive.carried.size(), 3u);  // loss, loss_scale, trusted_sigmas
  const std::string docs = test::ReadText(test::kFormatsDoc);
  const std::string profile = docs.substr(docs.find("## Profile JSON"));
  for (const auto& [key, profile_key] : archive.carried) {
    EXPECT_TRUE(archive.visited.count(key)) << key;
    EXPECT_NE(profile.find("\"" + profile_key + "\":"), std::string::npos) << profile_key;
  }
}

// docs/cli.md's rollout settings: a row per key of RolloutOptions and MotionFitOptions with its
// option, range and default, and no row for a key the visitors do not declare.
TEST(SettingsDocs, RolloutSettingsHaveTheirRowsInTheCliDocs) {
  RolloutOptions rollout;
  DocsArchive rolling("rollout", kCliDoc, /*options=*/true);
  Serialize(&rolling, &rollout);
  MotionFitOptions fit;
  DocsArchive fitting("motion_fit", kCliDoc, /*options=*/true);
  Serialize(&fitting, &fit);
  // The numeric keys were all visited (smooth_frames, error_tolerance; max_evaluations, range,
  // marker_sigma, rest_curvature_knots, rest_curvature_smoothness, gripper_prior_deg).
  EXPECT_EQ(rolling.keys(), 2);
  EXPECT_EQ(fitting.keys(), 6);
  EXPECT_EQ(RowKeys(kCliDoc, "rollout"), rolling.visited());
  EXPECT_EQ(RowKeys(kCliDoc, "motion_fit"), fitting.visited());
  EXPECT_EQ(rolling.visited().size(), 5u);
  EXPECT_EQ(fitting.visited().size(), 11u);  // with rest_start_from_first_frames, gripper_prior_deg
}

// MotionFitOptions::Check holds a library caller's values to the ranges the command line
// takes (one range per setting), naming the key.
TEST(SettingsDocs, MotionFitCheckUsesTheDeclaredRanges) {
  std::string why;
  EXPECT_TRUE(MotionFitOptions().Check(&why)) << why;
  MotionFitOptions o;
  o.rest_curvature_knots = 2;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_EQ(why, "rest_curvature_knots must be in [3, 200] (is 2)");
  o = MotionFitOptions();
  o.range = 1.0;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_EQ(why, "range must be > 1");
  o = MotionFitOptions();
  o.marker_sigma = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(o.Check(&why));
  EXPECT_EQ(why, "marker_sigma must be in [0, 1000000000] (is inf)");
  o = MotionFitOptions();
  o.max_evaluations = 0;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_EQ(why, "max_evaluations must be in [1, 100000] (is 0)");
}

}  // namespace
}  // namespace rodfit
