// The rollout's corpus of hard recordings (tests/solve/mocap_fixture.h, HardRecording): a whip
// of one gripper (free markers up to ~2.4 m/s), a pull to nearly straight, a loop and a fold,
// with 1 mm noise and 2 % drops. With its defaults — adaptive steps landing on every frame — no
// rollout aborts, at the frame interval and at 5 ms. Before adaptive steps the whip aborted at
// both ("did not converge in 50 Newton iterations ... halved 4 times" at t = 0.93 s and 0.90 s).
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/solve/rollout.h"
#include "solve/mocap_fixture.h"

namespace rodfit {
namespace {

using testing::HardMotion;

class HardRollout : public ::testing::TestWithParam<HardMotion> {};

TEST_P(HardRollout, NeverAbortsWithTheDefaults) {
  const std::vector<Eigen::Matrix3Xd> frames =
      testing::HardRecording(GetParam(), 2.0, 1e-3, 0.02, 3);
  for (double dt : {testing::kFrameInterval, 5e-3}) {
    SCOPED_TRACE(dt);
    Scene scene = testing::Cable();
    DefaultTwistDamping(&scene.material);  // as `rodfit rollout` does
    scene.dynamics->time_step = dt;
    const RolloutResult r = Rollout(scene, testing::kFrameInterval, frames, RolloutOptions());
    EXPECT_TRUE(r.ok) << r.reason;
    EXPECT_EQ(r.predicted.size(), frames.size());
    // The true parameters predict within a few centimetres (measured 2.7-20 mm: the pinned
    // pairs stand for the grippers).
    EXPECT_LT(r.mae_predicted, 0.03);
  }
}

INSTANTIATE_TEST_SUITE_P(Corpus, HardRollout,
                         ::testing::Values(HardMotion::kWhip, HardMotion::kPull,
                                           HardMotion::kLoop, HardMotion::kFold),
                         [](const ::testing::TestParamInfo<HardMotion>& info) {
                           return std::string(testing::HardMotionName(info.param));
                         });

}  // namespace
}  // namespace rodfit
