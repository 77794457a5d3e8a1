// RodModel::StretchedSpans: consecutive held points that the rod reaches only by stretching (a
// wire between two clamps measured farther apart than its length), named with their distance
// and the rod between them; within the strain allowed, nothing.
#include <gtest/gtest.h>

#include "rodfit/model/rod.h"
#include "solve/test_util.h"

namespace rodfit {
namespace {

RodModel TwoClamps(double end_x, bool with_pin) {
  Scene s = testing::Cantilever(20);
  s.rod.length = 0.6;
  LoadCase& c = s.cases[0];
  if (with_pin) c.pins.push_back(Pin{0.3, Vec3(0.3, 0.0, 0.0)});
  c.end_clamp = EndClamp{Vec3(end_x, 0.0, 0.0), Vec3::UnitX(), Vec3::UnitZ()};
  return RodModel(s.rod, s.material, s.gravity, c, s.springs);
}

TEST(HeldSpans, StretchedSpansAreNamedWithTheirDistances) {
  // 0.655 m apart with 0.6 m of rod: 9.17 % to stretch.
  const std::vector<std::string> one = TwoClamps(0.655, false).StretchedSpans(0.01);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0], "end_clamp (s = 0.6) is 0.655 m from the clamp (s = 0), 9.16667 % more than "
                    "the 0.6 m of rod between them: the rod must stretch to reach it");
  // Slack or within the strain allowed: nothing.
  EXPECT_TRUE(TwoClamps(0.45, false).StretchedSpans(0.01).empty());
  EXPECT_TRUE(TwoClamps(0.603, false).StretchedSpans(0.01).empty());
  // With a pin between: the span from the pin to the end clamp is the stretched one.
  const std::vector<std::string> pinned = TwoClamps(0.655, true).StretchedSpans(0.01);
  ASSERT_EQ(pinned.size(), 1u);
  EXPECT_NE(pinned[0].find("end_clamp (s = 0.6) is 0.355 m from pins[0] (s = 0.3)"),
            std::string::npos)
      << pinned[0];
}

}  // namespace
}  // namespace rodfit
