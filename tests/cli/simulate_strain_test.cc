// `simulate` warns when an equilibrium stretches the rod beyond a rod model's small strains
// (an end clamp placed beyond the rod's reach), and stays silent for an ordinary sag.
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "run_cli.h"

namespace rodfit::test {
namespace {

using ::testing::HasSubstr;

std::string Scene(const std::string& end_x) {
  return "rod: {length: 1.5, segments: 40, radius: 0.001, linear_density: 0.05}\n"
         "parameters:\n"
         "  bend_stiffness: {value: 1.0e-3}\n"
         "  twist_stiffness: {value: 8.0e-4}\n"
         "  stretch_stiffness: {value: 1.0e5}\n"
         "cases:\n"
         "  - name: wire\n"
         "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
         "    end_clamp: {position: [" + end_x + ", 0, 0], tangent: [1, 0, 0]}\n";
}

TEST(SimulateStrain, EndClampBeyondReachIsWarnedAbout) {
  TempDir dir;
  // 2 m between the clamps for a 1.5 m rod: a third of its length in stretch.
  const RunResult run = RunRodfit(
      dir, "simulate " + Quote(dir.Write("s.yaml", Scene("2"))) + " -o " + Quote(dir.File("o")));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.err, HasSubstr("case wire: an edge is strained by 33.3 %"));
}

TEST(SimulateStrain, OrdinarySagIsNot) {
  TempDir dir;
  const RunResult run = RunRodfit(
      dir, "simulate " + Quote(dir.Write("s.yaml", Scene("1"))) + " -o " + Quote(dir.File("o")));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");
}

}  // namespace
}  // namespace rodfit::test
