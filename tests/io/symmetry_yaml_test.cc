// The case key `symmetry: {point, normal}`: read into LoadCase::symmetry, and a case that is not
// its own mirror image refused at the key's line with the model's reason (SymmetryProblem).
#include <string>

#include <gtest/gtest.h>

#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit {
namespace {

// The YAML key: `symmetry: {point, normal}` in a case; a problem names the file and line.
TEST(Symmetry, YamlKeyAndItsErrors) {
  const std::string head =
      "rod: {length: 1.5, segments: 21, radius: 0.001, linear_density: 0.05}\n"
      "parameters:\n"
      "  bend_stiffness: {value: 0.001}\n"
      "  twist_stiffness: {value: 0.0008}\n"
      "  stretch_stiffness: {value: 100000}\n"
      "gravity: [0, 0, -9.81]\n"
      "cases:\n"
      "  - name: bridge\n"
      "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
      "    end_clamp: {position: [1, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n";
  const Experiment ex =
      ParseExperiment(head + "    symmetry: {point: [0.5, 0, 0], normal: [1, 0, 0]}\n", "s.yaml");
  ASSERT_TRUE(ex.scene.cases[0].symmetry.has_value());
  EXPECT_EQ(ex.scene.cases[0].symmetry->point, Vec3(0.5, 0, 0));
  EXPECT_EQ(ex.scene.cases[0].symmetry->normal, Vec3(1, 0, 0));
  auto error = [&](const std::string& text) -> std::string {
    try {
      ParseExperiment(text, "s.yaml");
    } catch (const InputError& e) {
      return e.what();
    }
    return "accepted";
  };
  EXPECT_EQ(error(head + "    symmetry: {point: [0.6, 0, 0], normal: [1, 0, 0]}\n"),
            "s.yaml:11: cases[0].symmetry: symmetry: the end_clamp's position is not the mirror "
            "image of the clamp's");
  EXPECT_EQ(error(head + "    symmetry: {point: [0.5, 0, 0], normal: [0, 0, 0]}\n"),
            "s.yaml:11: cases[0].symmetry.normal: must not be zero");
  EXPECT_EQ(error(head + "    symmetry: {point: [0.5, 0, 0]}\n"),
            "s.yaml:11: cases[0].symmetry.normal: missing required key");
  std::string even = head;
  even.replace(even.find("segments: 21"), 12, "segments: 20");
  EXPECT_EQ(error(even + "    symmetry: {point: [0.5, 0, 0], normal: [1, 0, 0]}\n"),
            "s.yaml:11: cases[0].symmetry: symmetry needs an odd number of segments (an edge "
            "crossing the plane at the rod's middle), got 20: use 19 or 21");
}

}  // namespace
}  // namespace rodfit
