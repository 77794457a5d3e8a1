// What issue 37 found wrong in the reports, checked on the bundled recipes as a lab runs them:
// the moving fit's report (data/suture_swing_fit) shows its residuals, iterations and timings,
// its markers over time and its run in 3-D over the recorded frames; the tissue drag's report
// lists every warning of the run with what to check and names its haptic samples without float
// noise; a rollout's report has its per-recording error table, each marker's path and the error
// over time, and its 3-D view steps through every frame.
#include <cstdio>
#include <regex>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_cli.h"

namespace rodfit::test {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

const std::string kSource = RODFIT_SOURCE_DIR;

// The figure of class `cls` (its <figure> element's text), empty when there is none.
std::string FigureOf(const std::string& html, const std::string& cls) {
  const size_t at = html.find("<figure class=\"fig " + cls + "\"");
  if (at == std::string::npos) return "";
  return html.substr(at, html.find("</figure>", at) - at);
}

// The JSON of the page's 3-D view `id`.
nlohmann::json ViewJson(const std::string& html, const std::string& id) {
  const std::string open = "<script type=\"application/json\" id=\"" + id + "-data\">";
  const size_t at = html.find(open);
  if (at == std::string::npos) return nullptr;
  const size_t start = at + open.size();
  return nlohmann::json::parse(html.substr(start, html.find("</script>", start) - start), nullptr,
                               false);
}

TEST(ReportMoving, TheSwingFitShowsResidualsIterationsTimingsAndItsRun) {
  TempDir dir;
  const RunResult fit = RunRodfit(dir, "fit " + Quote(kSource + "/data/suture_swing_fit/experiment.yaml") +
                                           " -o " + Quote(dir.File("p.json")) + " --report " +
                                           Quote(dir.File("r")) + " -q");
  ASSERT_EQ(fit.status, 0) << fit.err;
  const std::string html = ReadText(dir.File("r/index.html"));
  // Residuals: every recorded sample's three components in the histogram (94 samples seen,
  // summary.csv), not an empty one.
  const std::string histogram = FigureOf(html, "histogram");
  EXPECT_THAT(histogram, HasSubstr("residual components (282)"));
  EXPECT_THAT(histogram, Not(HasSubstr("no data")));
  // Iterations: the cost at the start and after each iteration (7 iterations: 8 points).
  const std::string cost = FigureOf(html, "cost-plot");
  EXPECT_THAT(cost, Not(HasSubstr("no iteration recorded")));
  std::smatch m;
  ASSERT_TRUE(std::regex_search(html, m, std::regex("<th>iterations</th><td class=\"num\">(\\d+)</td>")));
  const int iterations = std::stoi(m[1]);
  EXPECT_GT(iterations, 1);
  const std::regex point("<circle ");
  EXPECT_EQ(std::distance(std::sregex_iterator(cost.begin(), cost.end(), point), std::sregex_iterator()),
            iterations + 1 + 1);  // the points and the legend's marker
  // Timings: the runs with their sensitivities took time, and the row says how many.
  ASSERT_TRUE(std::regex_search(
      html, m,
      std::regex("runs of the moving cases with their sensitivities \\((\\d+) evaluations\\)</td>"
                 "<td class=\"num\"><span class=\"wall-time\">([0-9.]+)&nbsp;(ms|s)</span>")));
  EXPECT_GT(std::stoi(m[1]), 0);
  EXPECT_GT(std::stod(m[2]), 0.0);
  // Each marker's recorded and fitted coordinate over time, legend "s = 0.05 m" (not
  // "s = s = ...").
  const std::string markers = FigureOf(html, "sequence-trajectories");
  EXPECT_THAT(markers, HasSubstr(">s = 0.05 m</text>"));
  EXPECT_THAT(html, Not(HasSubstr("s = s =")));
  // The run in 3-D: a slider frame per recorded time (26 frames at 100 Hz over 0.25 s).
  const nlohmann::json view = ViewJson(html, "view3d-case-0");
  ASSERT_TRUE(view.is_object());
  EXPECT_EQ(view["frames"].size(), 26u);
  EXPECT_EQ(view["layout"]["sliders"][0]["steps"].size(), 26u);
  // Each frame holds the fitted centre-line and the samples recorded then.
  const nlohmann::json& frame = view["frames"][10];
  EXPECT_EQ(frame["data"][0]["name"], "fitted centre-line at t");
  EXPECT_GT(frame["data"][0]["x"].size(), 5u);
  EXPECT_GE(frame["data"][1]["x"].size(), 1u);
}

TEST(ReportMoving, TheTissueDragReportListsEveryWarningAndRoundedSampleTimes) {
  TempDir dir;
  const RunResult fit = RunRodfit(dir, "fit " + Quote(kSource + "/calibration/tissue_drag/experiment.yaml") +
                                           " -o " + Quote(dir.File("p.json")) + " --report " +
                                           Quote(dir.File("r")) + " -q");
  ASSERT_EQ(fit.status, 0) << fit.err;
  // stderr: the first and a count; the report: all five, each with what to check.
  EXPECT_THAT(fit.err, HasSubstr("and 4 more like it"));
  const std::string html = ReadText(dir.File("r/index.html"));
  EXPECT_THAT(html, HasSubstr("Warnings (5)"));
  const std::regex item("<li>case drag[^<]*the rod must stretch to reach it \\(check rod.length and "
                        "the held positions\\)</li>");
  EXPECT_EQ(std::distance(std::sregex_iterator(html.begin(), html.end(), item), std::sregex_iterator()), 5);
  // Haptic samples as a person reads their times.
  EXPECT_THAT(html, HasSubstr("case drag@t=3.065:"));
  EXPECT_THAT(html, Not(HasSubstr("0.16500000000000001")));
  // The grasp case's 3-D view steps through the samples: the case, then one per sample.
  const nlohmann::json view = ViewJson(html, "view3d-case-1");
  ASSERT_TRUE(view.is_object());
  ASSERT_GT(view["frames"].size(), 2u);
  EXPECT_EQ(view["layout"]["sliders"][0]["steps"][1]["label"], "0.165 s");
}

TEST(ReportMoving, TheRolloutReportHasItsErrorTable) {
  TempDir dir;
  const RunResult sim = RunRodfit(dir, "simulate " + Quote(kSource + "/data/scenes/cable_drive.yaml") +
                                           " -o " + Quote(dir.File("sim")) + " --markers 6");
  ASSERT_EQ(sim.status, 0) << sim.err;
  const RunResult run = RunRodfit(
      dir, "rollout " + Quote(kSource + "/data/scenes/cable_drive.yaml") + " " +
               Quote(dir.File("sim/markers.csv")) + " -o " + Quote(dir.File("out")) +
               " --report " + Quote(dir.File("report")) + " -q");
  ASSERT_EQ(run.status, 0) << run.err;
  const std::string html = ReadText(dir.File("report/index.html"));
  // The error table's row: the recording, its frames, markers and held ones, and the error
  // printed on stdout ("... m over the predicted ones").
  std::smatch m;
  ASSERT_TRUE(std::regex_search(run.out, m, std::regex("([0-9.e-]+) m over the predicted ones")));
  char mm[32];
  std::snprintf(mm, sizeof(mm), "%.3g&nbsp;mm", 1e3 * std::stod(m[1]));
  EXPECT_THAT(html, HasSubstr("<tr><td><code>markers.csv</code></td><td class=\"num\">201</td>"));
  EXPECT_THAT(html, HasSubstr("<td class=\"num\">6 (4)</td>"));
  EXPECT_THAT(html, HasSubstr(mm));
  EXPECT_TRUE(std::regex_search(html, std::regex("markers.csv: [xyz] of the predicted markers")));
  EXPECT_THAT(html, HasSubstr("markers.csv: error over time"));
  // The 3-D view steps through every frame (201 at 10 ms over 2 s).
  const nlohmann::json view = ViewJson(html, "view3d-recording-0");
  ASSERT_TRUE(view.is_object());
  EXPECT_EQ(view["frames"].size(), 201u);
  // --report onto -o's folder is refused before any work.
  const RunResult same = RunRodfit(dir, "rollout " + Quote(kSource + "/data/scenes/cable_drive.yaml") +
                                            " " + Quote(dir.File("sim/markers.csv")) + " -o " +
                                            Quote(dir.File("x")) + " --report " + Quote(dir.File("x")));
  EXPECT_EQ(same.status, 1);
  EXPECT_THAT(same.err, HasSubstr("--report DIR must differ from -o DIR"));
}

}  // namespace
}  // namespace rodfit::test
