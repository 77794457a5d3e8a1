// `rod.rest_shape: FILE` in the scene YAML (docs/formats.md; docs/model.md, "Rest shape"): the
// centre-line becomes the rod's rest curvature profile, and a bad file is an InputError naming
// it.
#include <cmath>
#include <cstdio>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/experiment.h"
#include "temp_dir.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

std::string Scene(const std::string& rest_shape) {
  return "rod:\n"
         "  length: 0.3\n"
         "  segments: 30\n"
         "  radius: 1.0e-3\n"
         "  linear_density: 1.0e-2\n"
         "  rest_shape: " + rest_shape + "\n"
         "parameters:\n"
         "  bend_stiffness: {value: 1.0e-3}\n"
         "  twist_stiffness: {value: 8.0e-4}\n"
         "  stretch_stiffness: {value: 1000}\n"
         "gravity: [0, 0, 0]\n"
         "cases:\n"
         "  - name: rest\n"
         "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n";
}

TEST(RestShapeYaml, AnArcFileGivesItsCurvatureAndTheRestStateFollowsIt) {
  TempDir dir;
  // A quarter of a circle of radius 0.3 / (pi / 2) in the x-z plane, leaving +x towards +z.
  const double R = 0.3 / (M_PI / 2.0);
  std::string csv = "x,y,z\n";
  for (int k = 0; k <= 60; ++k) {
    const double phi = 0.5 * M_PI * k / 60.0;
    char row[96];
    std::snprintf(row, sizeof(row), "%.17g,0,%.17g\n", R * std::sin(phi), R * (1.0 - std::cos(phi)));
    csv += row;
  }
  dir.Write("arc.csv", csv);
  const Experiment ex = LoadExperiment(dir.Write("scene.yaml", Scene("arc.csv")));
  const RodSpec& rod = ex.scene.rod;
  ASSERT_FALSE(rod.rest_curvature_s.empty());
  for (const Vec3& k : rod.rest_curvature_profile) EXPECT_NEAR(k[1], 1.0 / R, 2e-3 / R);
  // Unloaded, the rod is the arc: its tip where the quarter circle ends (to the discretisation's
  // second order: 30 segments).
  const RodModel model(rod, ex.scene.material, ex.scene.gravity, ex.scene.cases[0]);
  const RodState rest = model.RestState();
  EXPECT_LT((rest.x.col(30) - Vec3(R, 0.0, R)).norm(), 1e-3);
}

TEST(RestShapeYaml, ABadFileIsNamed) {
  TempDir dir;
  dir.Write("two.csv", "x,y,z\n0,0,0\n1,0,0\n");
  try {
    LoadExperiment(dir.Write("scene.yaml", Scene("two.csv")));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("two.csv"));
    EXPECT_THAT(e.what(), HasSubstr("at least 3 points"));
  }
  try {
    LoadExperiment(dir.Write("scene2.yaml", Scene("missing.csv")));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("scene2.yaml"));
    EXPECT_THAT(e.what(), HasSubstr("rest_shape"));
  }
}

}  // namespace
}  // namespace rodfit
