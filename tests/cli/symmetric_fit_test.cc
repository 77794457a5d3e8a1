// A case declared symmetric (a wire between two mirror-image clamps) is synthesized from its
// half and fitted: markers along the whole wire and the end clamp's force, B recovered within
// its reported std band. The fit solves such a case as the whole rod (docs/formats.md).
#include <cmath>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_cli.h"

namespace rodfit::test {
namespace {

TEST(SymmetricFit, SynthesizedTwoClampWireRecoversB) {
  TempDir dir;
  const std::string protocol = dir.Write(
      "protocol.yaml",
      "rod: {length: 1.5, segments: 41, radius: 0.001, linear_density: 0.05}\n"
      "parameters:\n"
      "  bend_stiffness: {value: 1.0e-3, fit: true, min: 1.0e-5, max: 1.0e-1}\n"
      "  twist_stiffness: {value: 8.0e-4}\n"
      "  stretch_stiffness: {value: 1.0e5}\n"
      "gravity: [0, 0, -9.81]\n"
      "cases:\n"
      "  - name: bridge\n"
      "    clamp: {position: [0, 0, 0], tangent: [1, 0.5, 0.3], normal: [0, 0, 1]}\n"
      "    end_clamp: {position: [1, 0, 0], tangent: [1, -0.5, -0.3]}\n"
      "    symmetry: {point: [0.5, 0, 0], normal: [1, 0, 0]}\n"
      "    observations:\n"
      "      - {type: markers3d, file: m.csv, sigma: 1.0e-3, count: 12}\n"
      "      - {type: reaction, file: r.csv, sigma: 1.0e-3, point: end_clamp}\n");
  RunResult run = RunRodfit(dir, "synth " + Quote(protocol) + " -o " + Quote(dir.File("syn")) +
                                     " --seed 3");
  ASSERT_EQ(run.status, 0) << run.err;
  // Start the fit three times too stiff.
  const std::string experiment = dir.File("syn/experiment.yaml");
  dir.Write("syn/experiment.yaml", Replace(ReadText(experiment), "value: 1.0e-3, fit: true",
                                           "value: 3.0e-3, fit: true"));
  run = RunRodfit(dir, "fit " + Quote(experiment) + " -o " + Quote(dir.File("p.json")) + " -q");
  ASSERT_EQ(run.status, 0) << run.err;
  const nlohmann::json p = nlohmann::json::parse(ReadText(dir.File("p.json")));
  const double b = p["parameters"]["bend_stiffness"]["value"].get<double>();
  const double sd = p["parameters"]["bend_stiffness"]["std"].get<double>();
  EXPECT_GT(sd, 0.0);
  EXPECT_LT(sd, 0.05 * b);
  EXPECT_LE(std::abs(b - 1.0e-3), 3.0 * sd) << b << " +- " << sd;
}

}  // namespace
}  // namespace rodfit::test
