// The fit report's page, DIR/index.html (docs/formats.md, "Fit report"), rendered for every
// bundled recipe as a lab runs it (calibration/*, and the synthetic demo data/synth_demo after
// `rodfit synth`): a parameter table row per fitted parameter, the correlation table, one camera
// figure per case and camera (the camera image embedded where the experiment has one), two 3-D
// projections per marker case, axis labels with units and a legend on every figure with data,
// the residual plots and histogram, the force plots of a haptic log, the poked section, the cost
// per iteration and the timing split; every figure also as figures/*.svg; text from the input
// escaped. Also: no progress line when stderr is not a terminal.
#include <algorithm>
#include <filesystem>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "rodfit/io/experiment.h"
#include "run_cli.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit::test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;
using ::testing::Not;

const std::string kSource = RODFIT_SOURCE_DIR;

struct FigureTag {
  std::string cls;                            // after "fig "
  std::map<std::string, std::string> data;    // data-* attributes (as written, escaped)
  std::string body;                           // up to </figure>
};

std::vector<FigureTag> Figures(const std::string& html) {
  std::vector<FigureTag> out;
  const std::regex open("<figure class=\"fig ([a-z-]+)\"([^>]*)>");
  const std::regex attr(" data-([a-z]+)=\"([^\"]*)\"");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), open);
       it != std::sregex_iterator(); ++it) {
    FigureTag f;
    f.cls = (*it)[1];
    const std::string attrs = (*it)[2];
    for (auto a = std::sregex_iterator(attrs.begin(), attrs.end(), attr);
         a != std::sregex_iterator(); ++a)
      f.data[(*a)[1]] = (*a)[2];
    const size_t start = it->position() + it->length();
    const size_t end = html.find("</figure>", start);
    f.body = html.substr(start, end == std::string::npos ? std::string::npos : end - start);
    out.push_back(std::move(f));
  }
  return out;
}

std::vector<FigureTag> OfClass(const std::vector<FigureTag>& all, const std::string& cls) {
  std::vector<FigureTag> out;
  for (const FigureTag& f : all)
    if (f.cls == cls) out.push_back(f);
  return out;
}

// The axis labels of a figure's SVG, in order (x, then y).
std::vector<std::string> AxisLabels(const std::string& svg) {
  std::vector<std::string> out;
  const std::regex label("<text class=\"axis-label\"[^>]*>([^<]*)</text>");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), label);
       it != std::sregex_iterator(); ++it)
    out.push_back((*it)[1]);
  return out;
}

// Every figure: both axis labels present; a figure with data has a legend and no "no data";
// quantities carry a unit in brackets.
void ExpectReadableFigures(const std::vector<FigureTag>& figures) {
  for (const FigureTag& f : figures) {
    SCOPED_TRACE(f.cls + " " + (f.data.count("case") ? f.data.at("case") : ""));
    const std::vector<std::string> labels = AxisLabels(f.body);
    ASSERT_EQ(labels.size(), 2u);
    for (const std::string& l : labels) EXPECT_FALSE(l.empty());
    EXPECT_THAT(f.body, HasSubstr("class=\"legend\""));
    EXPECT_THAT(f.body, Not(HasSubstr("class=\"no-data\"")));
    EXPECT_THAT(f.body, HasSubstr("</svg>"));
    // Quantities with units; counts and the dimensionless cost have none.
    if (f.cls != "residual-plot" && f.cls != "histogram" && f.cls != "cost-plot") {
      for (const std::string& l : labels) EXPECT_THAT(l, ::testing::ContainsRegex("\\[.+\\]"));
    }
  }
}

class ReportPageTest : public ::testing::Test {
 protected:
  // Fits `experiment` with --report; returns index.html (and checks the files beside it).
  std::string FitWithReport(const std::string& experiment, json* profile = nullptr) {
    const RunResult run = RunRodfit(dir_, "fit " + Quote(experiment) + " -o " +
                                              Quote(dir_.File("p.json")) + " --report " +
                                              Quote(dir_.File("report")));
    EXPECT_TRUE(run.status == 0 || run.status == 4) << run.err;
    // stderr is a file here, not a terminal: no progress line (no carriage return).
    EXPECT_EQ(run.err.find('\r'), std::string::npos) << run.err;
    for (const char* name : {"index.html", "summary.csv", "residuals.csv"})
      EXPECT_TRUE(fs::is_regular_file(dir_.File("report/") + name)) << name;
    if (profile) *profile = json::parse(ReadText(dir_.File("p.json")));
    const std::string html = ReadText(dir_.File("report/index.html"));
    // Each figure on the page is also a file of its own, linked from its caption.
    const std::regex link("href=\"(figures/[^\"]+\\.svg)\"");
    int links = 0;
    for (auto it = std::sregex_iterator(html.begin(), html.end(), link);
         it != std::sregex_iterator(); ++it, ++links) {
      const std::string file = dir_.File("report/" + (*it)[1].str());
      EXPECT_TRUE(fs::is_regular_file(file)) << file;
      if (links == 0) {
        EXPECT_THAT(ReadText(file), ::testing::StartsWith("<svg xmlns="));
      }
    }
    EXPECT_EQ(links, static_cast<int>(Figures(html).size()));
    return html;
  }

  // Parameter rows by name, and the fitted parameters of the profile.
  static void ExpectParameterRows(const std::string& html, const json& profile) {
    std::set<std::string> fitted, rows;
    for (const auto& [name, p] : profile["parameters"].items())
      if (p["fitted"] == true) fitted.insert(name);
    const std::regex row("<tr class=\"parameter[^\"]*\" data-name=\"([a-z_0-9]+)\">");
    for (auto it = std::sregex_iterator(html.begin(), html.end(), row);
         it != std::sregex_iterator(); ++it)
      rows.insert((*it)[1]);
    EXPECT_FALSE(fitted.empty());
    EXPECT_EQ(rows, fitted);
    for (const std::string& name : fitted) {
      const json& p = profile["parameters"][name];
      if (p["identifiable"] == true) {
        // value ± std, the unit and the relative std in %.
        const std::regex cells("data-name=\"" + name +
                               "\"><td><code>[a-z_0-9]+</code></td><td class=\"num\">[^ ]+ ± "
                               "[^ ]+</td><td>[^<]+(<sup>[^<]+</sup>)?</td>"
                               "<td class=\"num\">[0-9.]+&nbsp;%</td><td>yes</td>");
        EXPECT_TRUE(std::regex_search(html, cells)) << name;
      }
    }
    EXPECT_THAT(html, HasSubstr("<table class=\"correlation\">"));
  }

  // One camera figure per (case, camera) of the experiment, and nothing else.
  static void ExpectCameraFigures(const std::vector<FigureTag>& figures,
                                  const std::string& experiment_path) {
    const Experiment e = LoadExperiment(experiment_path);
    std::multiset<std::pair<std::string, std::string>> expected, found;
    for (size_t c = 0; c < e.cases.size(); ++c) {
      std::set<std::string> cameras;
      for (const ObservationSpec& o : e.cases[c].observations)
        if (!o.camera.empty()) cameras.insert(fs::path(o.camera).stem().string());
      for (const std::string& cam : cameras) expected.insert({e.scene.cases[c].name, cam});
    }
    for (const FigureTag& f : OfClass(figures, "camera-view")) {
      found.insert({f.data.at("case"), f.data.at("camera")});
      const std::vector<std::string> labels = AxisLabels(f.body);
      EXPECT_EQ(labels, (std::vector<std::string>{"u [px]", "v [px]"}));
      EXPECT_THAT(f.body, HasSubstr(">fitted centre-line</text>"));
    }
    EXPECT_EQ(found, expected);
  }

  // Two projections per case with 3-D markers, in mm.
  static void ExpectShapeFigures(const std::vector<FigureTag>& figures,
                                 const std::string& experiment_path) {
    const Experiment e = LoadExperiment(experiment_path);
    std::multiset<std::string> expected, found;
    for (size_t c = 0; c < e.cases.size(); ++c)
      for (const ObservationSpec& o : e.cases[c].observations)
        if (o.type == "markers3d") {
          expected.insert(e.scene.cases[c].name);
          expected.insert(e.scene.cases[c].name);
          break;
        }
    for (const FigureTag& f : OfClass(figures, "shape-view")) {
      found.insert(f.data.at("case"));
      for (const std::string& l : AxisLabels(f.body))
        EXPECT_THAT(l, ::testing::MatchesRegex("[xyz] \\[mm\\]"));
      EXPECT_THAT(f.body, HasSubstr(">observed markers</text>"));
      EXPECT_THAT(f.body, HasSubstr(">fitted marker positions</text>"));
      EXPECT_THAT(f.body, HasSubstr("s = "));  // the markers' arc lengths
    }
    EXPECT_EQ(found, expected);
  }

  // The parts every report has: residuals per case, histogram, cost, timing.
  static void ExpectCommonParts(const std::string& html, const std::vector<FigureTag>& figures,
                                size_t cases) {
    EXPECT_EQ(OfClass(figures, "residual-plot").size(), cases);
    for (const FigureTag& f : OfClass(figures, "residual-plot")) {
      EXPECT_EQ(AxisLabels(f.body)[1], "residual, model − measured [σ]");
      EXPECT_THAT(f.body, HasSubstr(">±1 σ</text>"));
      EXPECT_THAT(f.body, HasSubstr(">±3 σ</text>"));
    }
    const std::vector<FigureTag> hist = OfClass(figures, "histogram");
    ASSERT_EQ(hist.size(), 1u);
    EXPECT_THAT(hist[0].body, HasSubstr(">N(0, 1) × count × bin</text>"));
    EXPECT_THAT(hist[0].body, HasSubstr("<rect x="));  // bars
    const std::vector<FigureTag> cost = OfClass(figures, "cost-plot");
    ASSERT_EQ(cost.size(), 1u);
    EXPECT_EQ(AxisLabels(cost[0].body)[0], "Levenberg–Marquardt iteration");
    EXPECT_THAT(html, HasSubstr("<table class=\"timing\">"));
    EXPECT_THAT(html, HasSubstr("forward solves ("));
    EXPECT_THAT(html, HasSubstr("<table class=\"rms\">"));
    ExpectReadableFigures(figures);
  }

  TempDir dir_;
};

TEST_F(ReportPageTest, SutureCantileverRecipe) {
  const std::string experiment = kSource + "/calibration/suture_cantilever/experiment.yaml";
  json profile;
  const std::string html = FitWithReport(experiment, &profile);
  const std::vector<FigureTag> figures = Figures(html);
  ExpectParameterRows(html, profile);
  ExpectCameraFigures(figures, experiment);
  ExpectShapeFigures(figures, experiment);
  ExpectCommonParts(html, figures, 4);
  // No image in this recipe: blank frames with the image border.
  for (const FigureTag& f : OfClass(figures, "camera-view")) {
    EXPECT_THAT(f.body, Not(HasSubstr("<image")));
    EXPECT_THAT(f.body, HasSubstr(">image border</text>"));
    EXPECT_THAT(f.body, ::testing::ContainsRegex(">s = 0\\.[0-9]+ m</text>"));  // markers' s
  }
  EXPECT_TRUE(OfClass(figures, "force-time").empty());
  EXPECT_TRUE(OfClass(figures, "section-view").empty());
  // The cost per iteration has one point per iteration and the start.
  const int iterations = profile["fit"]["iterations"].get<int>();
  const std::string cost = OfClass(figures, "cost-plot")[0].body;
  const std::regex circle("<circle ");
  EXPECT_EQ(std::distance(std::sregex_iterator(cost.begin(), cost.end(), circle),
                          std::sregex_iterator()),
            iterations + 1 + 1);  // + the legend's sample
}

TEST_F(ReportPageTest, TissueDragRecipeHasForcePlots) {
  const std::string experiment = kSource + "/calibration/tissue_drag/experiment.yaml";
  json profile;
  const std::string html = FitWithReport(experiment, &profile);
  const std::vector<FigureTag> figures = Figures(html);
  ExpectParameterRows(html, profile);
  ExpectCameraFigures(figures, experiment);  // none: no camera
  ExpectShapeFigures(figures, experiment);
  ExpectCommonParts(html, figures, 2);
  const std::vector<FigureTag> force = OfClass(figures, "force-time");
  ASSERT_EQ(force.size(), 1u);
  EXPECT_EQ(force[0].data.at("case"), "drag");
  EXPECT_EQ(force[0].data.at("entry"), "grasp_force drag_force.csv");
  EXPECT_EQ(AxisLabels(force[0].body),
            (std::vector<std::string>{"t [s]", "force on the instrument [N]"}));
  for (const char* part : {">fx log</text>", ">fz used (measured)</text>", ">fy fitted</text>"})
    EXPECT_THAT(force[0].body, HasSubstr(part));
  const std::vector<FigureTag> residuals = OfClass(figures, "force-residuals");
  ASSERT_EQ(residuals.size(), 1u);
  EXPECT_EQ(AxisLabels(residuals[0].body)[1], "force residual, model − measured [N]");
  EXPECT_THAT(residuals[0].body, HasSubstr(">±1 σ</text>"));
  // The force readings are among the drag case's residuals, in the same plot as its markers.
  int drag = 0;
  for (const FigureTag& f : OfClass(figures, "residual-plot")) {
    if (f.data.at("case") == "drag") {
      EXPECT_THAT(f.body, HasSubstr(">grasp_force drag_force.csv</text>"));
      EXPECT_THAT(f.body, HasSubstr(">markers3d drag_markers.csv</text>"));
      ++drag;
    }
  }
  EXPECT_EQ(drag, 1);
}

TEST_F(ReportPageTest, TissuePokeRecipeShowsTheSection) {
  const std::string experiment = kSource + "/calibration/tissue_poke/experiment.yaml";
  json profile;
  const std::string html = FitWithReport(experiment, &profile);
  const std::vector<FigureTag> figures = Figures(html);
  ExpectParameterRows(html, profile);
  ExpectCommonParts(html, figures, 2);
  const std::vector<FigureTag> sections = OfClass(figures, "section-view");
  std::set<std::string> cases;
  for (const FigureTag& f : sections) {
    cases.insert(f.data.at("case"));
    // A section across a rod along x: y and z in mm (primed where the section is tilted).
    const std::vector<std::string> labels = AxisLabels(f.body);
    ASSERT_EQ(labels.size(), 2u);
    EXPECT_THAT(labels[0], ::testing::MatchesRegex("y(′)? \\[mm\\]"));
    EXPECT_THAT(labels[1], ::testing::MatchesRegex("z(′)? \\[mm\\]"));
    for (const char* part : {">rest section</text>", ">fitted deformed section</text>",
                             ">measured side_surface.csv</text>|>measured down_surface.csv</text>"})
      EXPECT_THAT(f.body, ::testing::ContainsRegex(part));
  }
  EXPECT_EQ(cases, (std::set<std::string>{"side", "down"}));
}

TEST_F(ReportPageTest, SyntheticDemoEmbedsTheCameraImages) {
  // The demo with its images, synthesized as the README says.
  const RunResult synth = RunRodfit(
      dir_, "synth " + Quote(kSource + "/data/synth_demo/experiment.yaml") + " -o " +
                Quote(dir_.File("demo")) + " --seed 1");
  ASSERT_EQ(synth.status, 0) << synth.err;
  const std::string experiment = dir_.File("demo/experiment.yaml");
  json profile;
  const std::string html = FitWithReport(experiment, &profile);
  const std::vector<FigureTag> figures = Figures(html);
  ExpectParameterRows(html, profile);
  ExpectCameraFigures(figures, experiment);
  ExpectShapeFigures(figures, experiment);
  ExpectCommonParts(html, figures, 2);
  // Every camera of this demo has an image: embedded as a data: URI, nothing outside the page.
  for (const FigureTag& f : OfClass(figures, "camera-view")) {
    EXPECT_THAT(f.body, HasSubstr("<image "));
    EXPECT_THAT(f.body, HasSubstr("href=\"data:image/jpeg;base64,"));
    EXPECT_THAT(f.body, ::testing::ContainsRegex(">pixels extracted from [a-z_]+\\.png"
                                                 "( \\(1 in [0-9]+ of [0-9]+ shown\\))?</text>"));
  }
  // Both entries of cam_front in `sag` (pixels from a file and from the image) are in one figure.
  int sag_front = 0;
  for (const FigureTag& f : OfClass(figures, "camera-view")) {
    if (f.data.at("case") == "sag" && f.data.at("camera") == "cam_front") {
      EXPECT_THAT(f.body, HasSubstr(">observed sag_front_uv.csv</text>"));
      ++sag_front;
    }
  }
  EXPECT_EQ(sag_front, 1);
}

TEST_F(ReportPageTest, TextFromTheInputIsEscaped) {
  // The poke recipe with a case name full of markup (commas, double quotes and '/' are refused).
  const std::string recipe = kSource + "/calibration/tissue_poke/";
  for (const char* f : {"side_surface.csv", "down_surface.csv"})
    fs::copy_file(recipe + f, dir_.File(f));
  const std::string experiment = dir_.Write(
      "experiment.yaml",
      Replace(ReadText(recipe + "experiment.yaml"), "name: side",
              "name: \"<b>side & 'x'\""));
  const std::string html = FitWithReport(experiment);
  EXPECT_THAT(html, Not(HasSubstr("<b>side")));
  EXPECT_THAT(html, HasSubstr("&lt;b&gt;side &amp; &#39;x&#39;"));
  const std::vector<FigureTag> sections = OfClass(Figures(html), "section-view");
  ASSERT_EQ(sections.size(), 2u);
  EXPECT_EQ(sections[0].data.at("case"), "&lt;b&gt;side &amp; &#39;x&#39;");
  // Its figure file has a plain name.
  for (const auto& entry : fs::directory_iterator(dir_.File("report/figures")))
    EXPECT_THAT(entry.path().filename().string(), ::testing::MatchesRegex("[A-Za-z0-9_-]+\\.svg"));
}

}  // namespace
}  // namespace rodfit::test
