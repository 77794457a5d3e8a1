// `surface_points` in the experiment YAML, BuildFitInput and synth: the entry needs a
// poke in its case (else a one-line InputError naming the file, the line and the key), allows
// only file, sigma and count, loads into FitCase::surface_points with the scene's section, and
// synth writes `count` points on the deformed ring.
#include <cmath>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/synth/synth.h"
#include "rodfit/model/rod.h"
#include "rodfit/solve/poke.h"
#include "rodfit/solve/statics.h"
#include "temp_dir.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/synthesize.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

const char* const kScene =
    "rod: {length: 0.15, segments: 30, radius: 0.012, linear_density: 0.45}\n"    // 1
    "parameters:\n"                                                               // 2
    "  bend_stiffness: {value: 2.0e-4}\n"                                         // 3
    "  twist_stiffness: {value: 1.5e-4}\n"                                        // 4
    "  stretch_stiffness: {value: 40}\n"                                          // 5
    "  spring_stiffness: {value: 300}\n"                                          // 6
    "  ring_bend_stiffness: {value: 2.0e-5, fit: true}\n"                         // 7
    "  ring_stretch_stiffness: {value: 5.0}\n"                                    // 8
    "springs: [{from: 0.0, to: 0.15}]\n"                                          // 9
    "section: {radius: 0.012, nodes: 16}\n"                                       // 10
    "cases:\n"                                                                    // 11
    "  - name: side\n"                                                            // 12
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"   // 13
    "    poke: {s: 0.075, force: [0, -0.03, 0]}\n"                                // 14
    "    observations:\n"                                                         // 15
    "      - {type: surface_points, file: side.csv, sigma: 3.0e-5, count: 20}\n"  // 16
    "  - name: plain\n"                                                           // 17
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n";  // 18

std::string With(const std::string& from, const std::string& to) {
  std::string text = kScene;
  const size_t pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

TEST(SurfacePointsIo, WithoutPokeIsOneLineErrorNamingTheKey) {
  TempDir dir;
  const std::string path = dir.Write(
      "scene.yaml",
      std::string(kScene) +  // case `plain` (no poke) gets an entry
          "    observations:\n"                                                         // 19
          "      - {type: surface_points, file: plain.csv, sigma: 3.0e-5}\n");          // 20
  try {
    LoadExperiment(path);
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    EXPECT_THAT(m, HasSubstr(path + ":20: cases[1].observations[0].type:"));
    EXPECT_THAT(m, HasSubstr("no poke"));
  }
}

TEST(SurfacePointsIo, OnlyFileSigmaCount) {
  TempDir dir;
  for (const char* extra : {"s: [0.1]", "outliers: 0.1", "camera: c.yaml"}) {
    SCOPED_TRACE(extra);
    const std::string path =
        dir.Write("scene.yaml", With("count: 20}", std::string("count: 20, ") + extra + "}"));
    try {
      LoadExperiment(path);
      ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
      EXPECT_THAT(std::string(e.what()), HasSubstr(path + ":16: cases[0].observations[0]."));
      EXPECT_THAT(std::string(e.what()), HasSubstr("not allowed for type surface_points"));
    }
  }
}

TEST(SurfacePointsIo, SynthWritesPointsOnTheRingAndBuildFitInputLoadsThem) {
  TempDir dir;
  const std::string path = dir.Write("scene.yaml", kScene);
  const Experiment ex = LoadExperiment(path);
  SynthOptions options;
  options.add_noise = false;
  Synthesize(ex, dir.File("out"), options);
  const Experiment synth = LoadExperiment(dir.File("out/experiment.yaml"));
  const FitInput in = BuildFitInput(synth);
  ASSERT_TRUE(in.section.has_value());
  EXPECT_EQ(in.section->nodes, 16);
  ASSERT_EQ(in.cases.size(), 2u);
  // A case's surface point sets among its measurements.
  auto surface_points = [](const FitCase& c) {
    std::vector<const SurfacePointSet*> sets;
    for (const auto& m : c.measurements)
      if (const auto* set = dynamic_cast<const SurfacePointSet*>(m.get())) sets.push_back(set);
    return sets;
  };
  ASSERT_EQ(surface_points(in.cases[0]).size(), 1u);
  const SurfacePointSet& sp = *surface_points(in.cases[0])[0];
  EXPECT_EQ(sp.points().size(), 20u);
  EXPECT_DOUBLE_EQ(sp.sample_sigma(0), 3e-5);
  EXPECT_EQ(sp.label(), "surface_points side.csv");
  EXPECT_TRUE(surface_points(in.cases[1]).empty());
  bool ring_fitted = false;
  for (const Parameter& p : in.parameters)
    if (p.name == "ring_bend_stiffness") ring_fitted = p.fit;
  EXPECT_TRUE(ring_fitted);

  // Noise-free points lie on the deformed ring, in the section's plane.
  const Scene& scene = ex.scene;
  const RodModel model(scene.rod, scene.material, scene.gravity, scene.cases[0], scene.springs);
  RodState state = model.StraightState();
  ASSERT_TRUE(SolveStatics(model, StaticsOptions(), &state).converged);
  const PokeResult poke = SolvePoke(model, state, *scene.section, {2e-5, 5.0});
  const int n = static_cast<int>(poke.deformed_world.cols());
  for (const Eigen::Vector3d& q : sp.points()) {
    EXPECT_NEAR((q - poke.placement.centre).dot(poke.placement.normal()), 0.0, 1e-12);
    double best = 1e9;
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3d a = poke.deformed_world.col(k), b = poke.deformed_world.col((k + 1) % n);
      const double t = std::clamp((q - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
      best = std::min(best, (a + t * (b - a) - q).norm());
    }
    EXPECT_LT(best, 1e-12);
  }
}

}  // namespace
}  // namespace rodfit
