// Rollout of a recorded motion (solve/rollout.h) on a synthetic motion-capture sequence of the
// form the held-out lab data has: a 1 m cable held at both ends by two grippers that move it,
// 12 markers at 100 Hz, ~1 mm noise and dropped samples. With the true parameters the open-loop
// prediction of the free markers stays at the noise level; a rod that is far too stiff does not.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/solve/case_dynamics.h"
#include "rodfit/solve/rollout.h"
#include "solve/mocap_fixture.h"

namespace rodfit {
namespace {

using testing::Cable;
using testing::kFrameInterval;
using testing::Recording;

TEST(Rollout, TrueParametersPredictTheFreeMarkersNearTheNoiseLevel) {
  const std::vector<Eigen::Matrix3Xd> frames = Recording(1.5, 1e-3, 0.02, 7);
  Scene model = Cable();
  const RolloutResult good = Rollout(model, kFrameInterval, frames, RolloutOptions());
  ASSERT_TRUE(good.ok) << good.reason;
  EXPECT_EQ(good.predicted.size(), frames.size());
  // Measured: 4.6 mm (4.0 mm without noise: the pins at markers 1 and n-2 stand for the
  // grippers' clamps, and the start's velocity is a 10 ms difference); a rod 100 times too
  // stiff in bending and twist: 12 mm.
  EXPECT_LT(good.mae_predicted, 5e-3) << good.mae_all;
  Scene stiff = model;
  stiff.material.bend_stiffness *= 100.0;
  stiff.material.twist_stiffness *= 100.0;
  const RolloutResult bad = Rollout(stiff, kFrameInterval, frames, RolloutOptions());
  ASSERT_TRUE(bad.ok) << bad.reason;
  EXPECT_GT(bad.mae_predicted, 2.0 * good.mae_predicted);
}

TEST(Rollout, RefusesUnusableRecordings) {
  std::vector<Eigen::Matrix3Xd> frames(3, Eigen::Matrix3Xd::Random(3, 5));
  frames[1](0, 2) = std::nan("");
  Scene s = Cable();
  EXPECT_THROW(Rollout(s, kFrameInterval, frames, RolloutOptions()), std::invalid_argument);
  RolloutOptions no_clamp;
  no_clamp.held_markers = {1, -1};
  frames[1](0, 2) = 0.0;
  EXPECT_THROW(Rollout(s, kFrameInterval, frames, no_clamp), std::invalid_argument);
  Scene no_dynamics = s;
  no_dynamics.dynamics.reset();
  EXPECT_THROW(Rollout(no_dynamics, kFrameInterval, frames, RolloutOptions()), std::invalid_argument);
}

}  // namespace
}  // namespace rodfit
