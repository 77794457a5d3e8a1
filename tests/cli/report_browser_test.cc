// Every bundled recipe's report opened in a real browser (headless Chromium, Debian's
// `chromium`, which scripts/install_deps.sh --tests installs): the static suture cantilever, the
// tissue drag and poke, the moving suture swing and a rollout of the cable recording. Each page
// is loaded with "#check3d", for which its script (report/view3d.h) draws every interactive 3-D
// view, reads each back as an image and writes a summary into the page: the test asserts one
// view per case (per recording for the rollout), each with drawn WebGL content (non-background
// pixels), and no script error on the page or on the browser's console.
//
// Without chromium the tests are skipped, unless RODFIT_BROWSER_REQUIRED=1 (scripts/test.sh and
// so CI set it), where they fail.
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_cli.h"

namespace rodfit::test {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

const std::string kSource = RODFIT_SOURCE_DIR;

// A view whose image has fewer non-background pixels than this drew nothing but its axes'
// frame: an empty 3-D scene of 480 x 360 px has ~1-2 thousand (grid lines, axis labels are
// light grey and text; measured 13,000-16,000 for the recipes' views), so a rod, markers and
// a tube are well above it.
constexpr int kMinDrawnPixels = 4000;

bool HaveChromium() { return std::system("command -v chromium >/dev/null 2>&1") == 0; }

#define REQUIRE_CHROMIUM()                                                                   \
  do {                                                                                       \
    if (!HaveChromium()) {                                                                   \
      const char* required = std::getenv("RODFIT_BROWSER_REQUIRED");                         \
      if (required && std::string(required) == "1")                                          \
        FAIL() << "chromium is not installed (bash scripts/install_deps.sh --tests)";        \
      GTEST_SKIP() << "chromium is not installed (bash scripts/install_deps.sh --tests)";    \
    }                                                                                        \
  } while (0)

struct BrowserCheck {
  nlohmann::json summary;  // {"views": n, "drawn": [...], "errors": [...]}, null if absent
  std::string console;     // the browser's console lines that are errors
};

// Loads `page` in headless Chromium with the flags that keep it off the network and out of any
// user profile; WebGL runs on SwiftShader (software), which headless needs without a GPU.
BrowserCheck Load(const TempDir& dir, const std::string& page) {
  const std::string profile = dir.File("chromium-profile");
  fs::create_directories(profile);
  const std::string dom = dir.File("dom.html"), log = dir.File("chromium.log");
  const std::string command =
      "timeout 180 chromium --headless --no-sandbox --disable-gpu --enable-unsafe-swiftshader "
      "--disable-background-networking --disable-component-update --disable-sync "
      "--no-first-run --user-data-dir=" + Quote(profile) +
      " --enable-logging=stderr --v=0 --virtual-time-budget=30000 --dump-dom " +
      Quote("file://" + fs::absolute(page).string() + "#check3d") + " >" + Quote(dom) + " 2>" +
      Quote(log);
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
  BrowserCheck out;
  const std::string html = ReadText(dom);
  std::smatch m;
  if (std::regex_search(html, m, std::regex("<pre id=\"rodfit-check3d\">([^<]*)</pre>")))
    out.summary = nlohmann::json::parse(m[1].str(), nullptr, false);
  // Console lines: an uncaught exception or an error logged by a script (the page's own
  // recorder catches the same; this also sees errors before it runs).
  const std::string text = ReadText(log);
  const std::regex line("[^\n]*CONSOLE[^\n]*");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), line); it != std::sregex_iterator();
       ++it) {
    const std::string l = it->str();
    if (l.find("Uncaught") != std::string::npos || l.find(":ERROR:CONSOLE") != std::string::npos)
      out.console += l + "\n";
  }
  return out;
}

void ExpectDrawn(const BrowserCheck& check, int views) {
  ASSERT_TRUE(check.summary.is_object()) << "the page wrote no #check3d summary";
  EXPECT_EQ(check.summary["views"], views);
  ASSERT_EQ(check.summary["drawn"].size(), static_cast<size_t>(views));
  for (const auto& n : check.summary["drawn"]) EXPECT_GE(n.get<int>(), kMinDrawnPixels);
  EXPECT_TRUE(check.summary["errors"].empty()) << check.summary["errors"].dump();
  EXPECT_EQ(check.console, "");
}

// The fit report of a recipe, loaded: one view per case.
void CheckFitReport(const std::string& experiment, int cases) {
  TempDir dir;
  const RunResult fit = RunRodfit(dir, "fit " + Quote(kSource + "/" + experiment) + " -o " +
                                           Quote(dir.File("profile.json")) + " --report " +
                                           Quote(dir.File("report")) + " -q");
  ASSERT_EQ(fit.status, 0) << fit.err;
  // A report written without plotly.js says so on stderr and has no view to draw.
  EXPECT_THAT(fit.err, Not(HasSubstr("plotly.js not found")));
  ExpectDrawn(Load(dir, dir.File("report/index.html")), cases);
}

TEST(ReportBrowser, SutureCantileverDrawsEveryCaseIn3d) {
  REQUIRE_CHROMIUM();
  CheckFitReport("calibration/suture_cantilever/experiment.yaml", 4);
}

TEST(ReportBrowser, TissueDragDrawsEveryCaseIn3d) {
  REQUIRE_CHROMIUM();
  CheckFitReport("calibration/tissue_drag/experiment.yaml", 2);
}

TEST(ReportBrowser, TissuePokeDrawsTheDentedTubes) {
  REQUIRE_CHROMIUM();
  CheckFitReport("calibration/tissue_poke/experiment.yaml", 2);
}

TEST(ReportBrowser, MovingFitDrawsItsRunOverTime) {
  REQUIRE_CHROMIUM();
  CheckFitReport("data/suture_swing_fit/experiment.yaml", 1);
}

TEST(ReportBrowser, RolloutReportDrawsTheRecording) {
  REQUIRE_CHROMIUM();
  TempDir dir;
  const RunResult sim = RunRodfit(dir, "simulate " + Quote(kSource + "/data/scenes/cable_drive.yaml") +
                                           " -o " + Quote(dir.File("sim")) + " --markers 10");
  ASSERT_EQ(sim.status, 0) << sim.err;
  const RunResult run = RunRodfit(dir, "rollout " + Quote(kSource + "/data/scenes/cable_drive.yaml") +
                                           " " + Quote(dir.File("sim/markers.csv")) + " -o " +
                                           Quote(dir.File("rollout")) + " --report " +
                                           Quote(dir.File("report")) + " -q");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.err, Not(HasSubstr("plotly.js not found")));
  // The page's error table names the recording.
  EXPECT_THAT(ReadText(dir.File("report/index.html")), HasSubstr("<code>markers.csv</code>"));
  ExpectDrawn(Load(dir, dir.File("report/index.html")), 1);
}

}  // namespace
}  // namespace rodfit::test
