// The fit report's residuals.csv lists every measurement the fit used: besides markers, points
// and pixels, each force reading (N) of a haptic log and each surface point (m) of a poke, with
// its error vector and its norm in sigmas — the bundled tissue recipes, fitted as a lab would.
#include <cmath>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "run_cli.h"

namespace rodfit::test {
namespace {

struct Row {
  std::string unit;
  double norm = 0.0, norm_sigma = 0.0;
};

// residuals.csv rows by observation label.
std::map<std::string, std::vector<Row>> ReadResiduals(const std::string& path) {
  std::istringstream in(ReadText(path));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "case,observation,unit,measurement,e1,e2,e3,norm,norm_sigma");
  std::map<std::string, std::vector<Row>> rows;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    EXPECT_EQ(f.size(), 9u) << line;
    if (f.size() != 9) continue;
    rows[f[1]].push_back({f[2], std::stod(f[7]), std::stod(f[8])});
  }
  return rows;
}

TEST(ReportResiduals, ForceReadingsOfAHapticLogAreListed) {
  TempDir dir;
  const std::string experiment =
      std::string(RODFIT_SOURCE_DIR) + "/calibration/tissue_drag/experiment.yaml";
  const RunResult run = RunRodfit(dir, "fit " + Quote(experiment) + " -o " +
                                           Quote(dir.File("p.json")) + " -q --report " +
                                           Quote(dir.File("report")));
  ASSERT_EQ(run.status, 0) << run.err;
  const auto rows = ReadResiduals(dir.File("report/residuals.csv"));
  ASSERT_TRUE(rows.count("grasp_force drag_force.csv"));
  const std::vector<Row>& forces = rows.at("grasp_force drag_force.csv");
  EXPECT_EQ(forces.size(), 8u);  // the eight quasi-static samples the recipe keeps
  for (const Row& r : forces) {
    EXPECT_EQ(r.unit, "N");
    EXPECT_NEAR(r.norm_sigma, r.norm / 0.01, 1e-9 * r.norm_sigma + 1e-12);  // sigma 0.01 N
    EXPECT_LT(r.norm_sigma, 6.0);  // a fit with the right sigmas: no reading far off
  }
  EXPECT_EQ(rows.at("markers3d drag_markers.csv").size(), 10u);
}

TEST(ReportResiduals, SurfacePointsOfAPokeAreListed) {
  TempDir dir;
  const std::string experiment =
      std::string(RODFIT_SOURCE_DIR) + "/calibration/tissue_poke/experiment.yaml";
  const RunResult run = RunRodfit(dir, "fit " + Quote(experiment) + " -o " +
                                           Quote(dir.File("p.json")) + " -q --report " +
                                           Quote(dir.File("report")));
  ASSERT_EQ(run.status, 0) << run.err;
  const auto rows = ReadResiduals(dir.File("report/residuals.csv"));
  int surface = 0;
  for (const auto& [label, list] : rows) {
    if (label.rfind("surface_points", 0) != 0) continue;
    for (const Row& r : list) {
      EXPECT_EQ(r.unit, "m");
      EXPECT_TRUE(std::isfinite(r.norm_sigma));
      ++surface;
    }
  }
  EXPECT_GT(surface, 0) << "residuals.csv has no surface point rows";
}

}  // namespace
}  // namespace rodfit::test
