// Reproducible outputs: the same inputs and thread count give byte-identical files, and results do not
// depend on the thread count beyond 1e-12 relative. Run on the bundled recipes as a user runs them
// (README, "Calibration recipes"): the tissue_drag fit (two spring zones from markers and a
// haptic log: 10 cases evaluated in parallel) and the tissue_poke fit with their reports,
// `simulate` on the bowel drag scene, and `synth` of the drag protocol. No output holds wall time
// (the fit prints its time on stderr, simulate on stdout).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../io/temp_dir.h"
#include "run_cli.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::ReadText;
using test::RunResult;
using test::TempDir;
using ::testing::HasSubstr;

const std::string kRecipes = RODFIT_SOURCE_DIR "/calibration/";

/// Results independent of the thread count to this relative tolerance.
constexpr double kThreadTolerance = 1e-12;

std::string Q(const std::string& s) { return test::Quote(s); }

// Every regular file under dir, by relative path, with its bytes.
std::map<std::string, std::string> Files(const std::string& dir) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (entry.is_regular_file())
      files[fs::relative(entry.path(), dir).string()] = ReadText(entry.path().string());
  }
  return files;
}

// Two JSON documents equal in structure, text and booleans, their numbers within `tolerance`
// relative (absolute below 1e-300); `where` names the first difference.
bool Near(const json& a, const json& b, double tolerance, std::string* where,
          const std::string& path = "") {
  if (a.is_number() && b.is_number()) {
    const double x = a.get<double>(), y = b.get<double>();
    const double scale = std::max({std::abs(x), std::abs(y), 1e-300});
    if (std::abs(x - y) <= tolerance * scale) return true;
    *where = path + ": " + a.dump() + " vs " + b.dump();
    return false;
  }
  if (a.type() != b.type() || a.size() != b.size()) {
    *where = path + ": " + a.dump().substr(0, 80) + " vs " + b.dump().substr(0, 80);
    return false;
  }
  if (a.is_object()) {
    for (auto it = a.begin(); it != a.end(); ++it) {
      if (!b.contains(it.key())) {
        *where = path + "." + it.key() + " missing";
        return false;
      }
      if (!Near(it.value(), b.at(it.key()), tolerance, where, path + "." + it.key())) return false;
    }
    return true;
  }
  if (a.is_array()) {
    for (size_t i = 0; i < a.size(); ++i)
      if (!Near(a[i], b[i], tolerance, where, path + "[" + std::to_string(i) + "]")) return false;
    return true;
  }
  if (a == b) return true;
  *where = path + ": " + a.dump() + " vs " + b.dump();
  return false;
}

class DeterminismTest : public ::testing::Test {
 protected:
  // `rodfit fit` of a recipe with --threads N into out/NAME (profile.json and report/).
  std::map<std::string, std::string> Fit(const std::string& recipe, const std::string& name,
                                         int threads) {
    const std::string out = dir_.File(name);
    const RunResult run =
        test::RunRodfit(dir_, "fit " + Q(kRecipes + recipe + "/experiment.yaml") + " -o " +
                                  Q(out + "/profile.json") + " --report " + Q(out + "/report") +
                                  " --threads " + std::to_string(threads));
    EXPECT_TRUE(run.status == 0 || run.status == 4) << run.err;
    // The time is on stderr, not in a file.
    EXPECT_THAT(run.err, HasSubstr(" s, residual variance"));
    return Files(out);
  }

  TempDir dir_;
};

// The report page marks its wall times (class "wall-time"): they, and only they, may differ.
std::string WithoutWallTimes(const std::string& name, std::string bytes) {
  if (name.size() < 5 || name.substr(name.size() - 5) != ".html") return bytes;
  const std::string open = "<span class=\"wall-time\">", close = "</span>";
  for (size_t at = bytes.find(open); at != std::string::npos; at = bytes.find(open, at + 1)) {
    const size_t end = bytes.find(close, at);
    if (end == std::string::npos) break;
    bytes.erase(at + open.size(), end - at - open.size());
  }
  return bytes;
}

TEST_F(DeterminismTest, TissueFitsAreByteIdenticalRunToRunAndAcrossThreadCounts) {
  for (const char* recipe : {"tissue_drag", "tissue_poke"}) {
    SCOPED_TRACE(recipe);
    const auto first = Fit(recipe, std::string(recipe) + "_a", 2);
    const auto again = Fit(recipe, std::string(recipe) + "_b", 2);
    const auto one = Fit(recipe, std::string(recipe) + "_1", 1);
    ASSERT_TRUE(first.count("profile.json"));
    ASSERT_TRUE(first.count("report/summary.csv"));
    // Nothing in the profile that changes from run to run.
    const json profile = json::parse(first.at("profile.json"));
    EXPECT_FALSE(profile["fit"].contains("time_s"));
    // The same thread count: every file byte for byte (the profile, tables and plots).
    EXPECT_EQ(first.size(), again.size());
    for (const auto& [name, bytes] : first) {
      ASSERT_TRUE(again.count(name)) << name;
      EXPECT_TRUE(WithoutWallTimes(name, bytes) == WithoutWallTimes(name, again.at(name)))
          << name << " differs between two runs";
    }
    // One thread against two: the same files, numbers within 1e-12 relative (the cases'
    // residuals are summed in a fixed order, so they are in fact the same bytes).
    ASSERT_EQ(first.size(), one.size());
    std::string where;
    EXPECT_TRUE(Near(profile, json::parse(one.at("profile.json")), kThreadTolerance, &where))
        << where;
    for (const auto& [name, bytes] : first) {
      ASSERT_TRUE(one.count(name)) << name;
      EXPECT_TRUE(WithoutWallTimes(name, bytes) == WithoutWallTimes(name, one.at(name)))
          << name << " differs between --threads 1 and 2";
    }
  }
}

TEST_F(DeterminismTest, SimulateAndSynthAreByteIdenticalRunToRun) {
  for (const char* run_name : {"a", "b"}) {
    RunResult run = test::RunRodfit(dir_, "simulate " +
                                              Q(RODFIT_SOURCE_DIR "/data/scenes/bowel_drag.yaml") +
                                              " -o " + Q(dir_.File(std::string("sim_") + run_name)));
    ASSERT_EQ(run.status, 0) << run.err;
    EXPECT_THAT(run.out, HasSubstr("cases in"));  // the time is printed, not written
    run = test::RunRodfit(dir_, "synth " + Q(kRecipes + "tissue_drag/protocol.yaml") + " -o " +
                                    Q(dir_.File(std::string("synth_") + run_name)) + " --seed 5");
    ASSERT_EQ(run.status, 0) << run.err;
  }
  const auto sim_a = Files(dir_.File("sim_a")), sim_b = Files(dir_.File("sim_b"));
  ASSERT_TRUE(sim_a.count("summary.csv"));
  EXPECT_EQ(sim_a.at("summary.csv").find("seconds"), std::string::npos);
  EXPECT_TRUE(sim_a == sim_b);
  const auto synth_a = Files(dir_.File("synth_a")), synth_b = Files(dir_.File("synth_b"));
  ASSERT_TRUE(synth_a.count("truth.json"));
  EXPECT_TRUE(synth_a == synth_b);
}

}  // namespace
}  // namespace rodfit
