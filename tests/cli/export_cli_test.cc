// `rodfit export` as a hostile user would run it (issue 34): the output rule every command keeps
// (never over a FIFO, a directory or an input, never to an empty path: refused with one line,
// exit 1, nothing changed), and every export validated before anything is written (json
// refusing what the other formats refuse; no nan or inf from hostile radii or damping, --set
// included). Each case is one of the defects the issue lists.
#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_cli.h"

namespace rodfit {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;
using test::Quote;
using test::RunRodfit;
using test::TempDir;
namespace fs = std::filesystem;

const std::string kSuture = std::string(RODFIT_SOURCE_DIR) + "/data/profiles/suture.json";

void ExpectOneLineError(const test::RunResult& run, const std::string& fragment) {
  EXPECT_EQ(run.status, 1) << run.err;
  EXPECT_THAT(run.err, StartsWith("rodfit"));
  EXPECT_THAT(run.err, HasSubstr(fragment));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
}

// Only the given entries are in the folder (no temporary file left behind).
void ExpectOnly(const TempDir& dir, std::set<std::string> names) {
  names.insert({"stdout.txt", "stderr.txt"});
  std::set<std::string> found;
  for (const auto& entry : fs::directory_iterator(dir.path()))
    found.insert(entry.path().filename().string());
  EXPECT_EQ(found, names);
}

TEST(ExportCli, OutputsNeverGoOverAFifoADirectoryAnInputOrAnEmptyPath) {
  TempDir dir;
  const std::string profile = dir.Write("p.json", test::ReadText(kSuture));
  const std::string fifo = dir.File("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0666), 0);
  fs::create_directory(dir.File("folder"));
  for (const char* format : {"json", "sofa", "mujoco"}) {
    SCOPED_TRACE(format);
    const std::string base = "export " + Quote(profile) + " --format " + format + " -o ";
    test::RunResult run = RunRodfit(dir, base + Quote(fifo));
    ExpectOneLineError(run, "exists and is not a file");
    EXPECT_TRUE(fs::is_fifo(fifo));
    run = RunRodfit(dir, base + Quote(dir.File("folder")));
    ExpectOneLineError(run, "folder");
    EXPECT_TRUE(fs::is_directory(dir.File("folder")));
    EXPECT_TRUE(fs::is_empty(dir.File("folder")));
    run = RunRodfit(dir, base + "''");
    ExpectOneLineError(run, "-o is empty");
    run = RunRodfit(dir, base + Quote(dir.File("folder") + "/"));
    ExpectOneLineError(run, "is not a file name");
    run = RunRodfit(dir, base + Quote(profile));
    ExpectOneLineError(run, "is the profile");
    EXPECT_EQ(test::ReadText(profile), test::ReadText(kSuture));
    ExpectOnly(dir, {"p.json", "fifo", "folder"});
  }
  // And a plain file is written, replacing what was there.
  dir.Write("out.json", "old");
  ASSERT_EQ(RunRodfit(dir, "export " + Quote(profile) + " --format json -o " +
                               Quote(dir.File("out.json"))).status, 0);
  EXPECT_EQ(nlohmann::json::parse(test::ReadText(dir.File("out.json"))),
            nlohmann::json::parse(test::ReadText(kSuture)));
}

TEST(ExportCli, HostileProfilesAreRefusedByEveryFormatWithNothingWritten) {
  TempDir dir;
  const nlohmann::json suture = nlohmann::json::parse(test::ReadText(kSuture));
  struct Case {
    const char* name;
    nlohmann::json doc;
    const char* set;  // --set, or ""
    const char* message;
  };
  std::vector<Case> cases;
  auto with = [&](const char* name, auto edit, const char* set, const char* message) {
    nlohmann::json doc = suture;
    edit(doc);
    cases.push_back({name, doc, set, message});
  };
  with("stiff", [](nlohmann::json& d) { d["parameters"]["bend_stiffness"]["value"] = 1e308; }, "",
       "parameters.bend_stiffness.value: 1e+308 is beyond 1e+30");
  with("far_pin", [](nlohmann::json& d) { d["held"]["end_pin"] = {10.0, 0.0, 0.0}; },
       "", "end_pin (s = 0.2) is 10 m from the clamp");
  with("two_pins",
       [](nlohmann::json& d) {
         d["held"]["pins"] = {{{"s", 0.1}, {"position", {0.1, 0.0, 0.0}}},
                              {{"s", 0.1001}, {"position", {0.1, 0.0, 0.0}}}};
       },
       "", "pins");
  with("wide", [](nlohmann::json& d) { d["rod"]["radius"] = 1e308; }, "", "rod.radius: 1e+308 m");
  with("thin", [](nlohmann::json& d) { d["rod"]["radius"] = 1e-300; }, "", "rod.radius: 1e-300 m");
  with("damped", [](nlohmann::json& d) { d["parameters"]["damping"]["value"] = 1e308; }, "",
       "parameters.damping.value: 1e+308 is beyond 1e+30");
  with("set_damped", [](nlohmann::json&) {}, "damping=1e308",
       "parameters.damping.value: 1e+308 is beyond 1e+30 (--set damping)");
  // linear_density's physical range [1e-15, 1e5] kg/m (material_parameters.h): 1e-300 kg/m
  // would divide the drag cells and the stable step by nothing.
  with("light", [](nlohmann::json& d) { d["rod"]["linear_density"] = 1e-300; }, "",
       "rod.linear_density 1e-300 kg/m is outside its physical range [1e-15, 100000] kg/m");
  with("light_parameter",
       [](nlohmann::json& d) {
         d["rod"]["linear_density"] = 1e-300;
         d["parameters"]["linear_density"] = {{"value", 1e-300}, {"unit", "kg/m"}};
       },
       "",
       "parameters.linear_density.value: 1e-300 is below 1e-15, outside linear_density's "
       "physical range [1e-15, 100000] kg/m");
  with("set_light",
       [](nlohmann::json& d) {
         d["parameters"]["linear_density"] = {{"value", d["rod"]["linear_density"]},
                                              {"unit", "kg/m"}};
       },
       "linear_density=1e-300",
       "parameters.linear_density.value: 1e-300 is below 1e-15 (--set linear_density), outside "
       "linear_density's physical range");
  for (const Case& c : cases) {
    const std::string path = dir.Write(std::string(c.name) + ".json", c.doc.dump(1));
    for (const char* format : {"json", "sofa", "mujoco", "xpbd"}) {
      if (*c.set && std::string(format) == "json") continue;  // json takes no --set
      SCOPED_TRACE(std::string(c.name) + " as " + format);
      const std::string out = dir.File("out");
      std::string args = "export " + Quote(path) + " --format " + format + " -o " + Quote(out);
      if (std::string(format) == "xpbd") args += " --time-step 1e-3";
      if (*c.set) args += std::string(" --set ") + c.set;
      const test::RunResult run = RunRodfit(dir, args);
      ExpectOneLineError(run, path + ": ");
      EXPECT_THAT(run.err, HasSubstr(c.message));
      EXPECT_FALSE(fs::exists(out));
    }
  }
}

TEST(ExportCli, MujocoAndSofaScenesAreWritten) {
  TempDir dir;
  for (const char* format : {"mujoco", "sofa"}) {
    const std::string out = dir.File(std::string("rod.") + format + ".xml");
    const test::RunResult run = RunRodfit(
        dir, "export " + Quote(kSuture) + " --format " + format + " --time-step 2e-5 -o " + Quote(out));
    ASSERT_EQ(run.status, 0) << run.err;
    const std::string text = test::ReadText(out);
    EXPECT_THAT(text, HasSubstr(std::string(format) == "mujoco" ? "<option timestep=\"2.0000000000000002e-05\""
                                                                 : "dt=\"2.0000000000000002e-05\""));
  }
  const test::RunResult help = RunRodfit(dir, "export --help");
  for (const char* name : {"sofa:", "mujoco:", "xpbd:", "json:"}) EXPECT_THAT(help.out, HasSubstr(name));
}

}  // namespace
}  // namespace rodfit
