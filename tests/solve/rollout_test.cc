// Rollout of a recorded motion (solve/rollout.h) on a synthetic motion-capture sequence of the
// form the held-out lab data has: a 1 m cable held at both ends by two grippers that move it,
// 12 markers at 100 Hz, ~1 mm noise and dropped samples. With the true parameters the open-loop
// prediction of the free markers stays at the noise level; a rod that is far too stiff does not.
#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include <Eigen/SVD>
#include <gtest/gtest.h>

#include "rodfit/solve/case_dynamics.h"
#include "rodfit/solve/rollout.h"
#include "solve/mocap_fixture.h"

namespace rodfit {
namespace {

using testing::Cable;
using testing::kFrameInterval;
using testing::Recording;

// The baseline of the held-out data's protocol: the first frame's shape carried rigidly by the
// held markers (the rotation and translation that best map them from frame 0 to frame k,
// Kabsch), scored like the rollout: the mean absolute coordinate error of the free markers.
double RigidCarryError(const std::vector<Eigen::Matrix3Xd>& frames, const std::vector<int>& held) {
  const int M = static_cast<int>(frames[0].cols());
  std::vector<char> is_held(M, 0);
  for (int h : held) is_held[h < 0 ? M + h : h] = 1;
  double sum = 0.0;
  int n = 0;
  for (size_t k = 1; k < frames.size(); ++k) {
    Eigen::Matrix3Xd a(3, 0), b(3, 0);
    for (int m = 0; m < M; ++m) {
      if (!is_held[m] || !frames[k].col(m).allFinite()) continue;
      a.conservativeResize(3, a.cols() + 1);
      b.conservativeResize(3, b.cols() + 1);
      a.col(a.cols() - 1) = frames[0].col(m);
      b.col(b.cols() - 1) = frames[k].col(m);
    }
    if (a.cols() < 3) continue;
    const Vec3 ca = a.rowwise().mean(), cb = b.rowwise().mean();
    const Eigen::Matrix3d H = (a.colwise() - ca) * (b.colwise() - cb).transpose();
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
    const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
    for (int m = 0; m < M; ++m) {
      if (is_held[m] || !frames[k].col(m).allFinite()) continue;
      const Vec3 p = R * (frames[0].col(m) - ca) + cb;
      sum += (p - frames[k].col(m)).cwiseAbs().sum() / 3.0;
      ++n;
    }
  }
  return sum / n;
}

TEST(Rollout, TrueParametersBeatTheRigidCarryBaselineAndTheGoal) {
  const std::vector<Eigen::Matrix3Xd> frames = Recording(1.5, 1e-3, 0.02, 7);
  const RolloutResult good = Rollout(Cable(), kFrameInterval, frames, RolloutOptions());
  ASSERT_TRUE(good.ok) << good.reason;
  EXPECT_EQ(good.predicted.size(), frames.size());
  // Measured: 4.7 mm with the jaws (the default: clamps at markers 1 and n-2 along the chords
  // stand for the grippers' clamps at markers 0 and n-1; 5.0 mm with the pins there); the rigid
  // carry of the first shape, 13.5 mm; the goal for real recordings, 10 mm.
  const double rigid = RigidCarryError(frames, RolloutOptions().held_markers);
  EXPECT_LT(good.mae_predicted, 0.5 * rigid) << rigid;
  EXPECT_LT(good.mae_predicted, 1e-2);
  Scene stiff = Cable();
  stiff.material.bend_stiffness *= 100.0;
  stiff.material.twist_stiffness *= 100.0;
  const RolloutResult bad = Rollout(stiff, kFrameInterval, frames, RolloutOptions());
  ASSERT_TRUE(bad.ok) << bad.reason;
  EXPECT_GT(bad.mae_predicted, 1.5 * good.mae_predicted);  // measured 11.0 against 4.7 mm
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

// The exact tangent of a helix of radius r and pitch c (per radian) at arc length s, and its point.
Vec3 HelixPoint(double r, double c, double s) {
  const double w = s / std::hypot(r, c);
  return Vec3(r * std::cos(w), r * std::sin(w), c * w);
}
Vec3 HelixTangent(double r, double c, double s) {
  const double a = std::hypot(r, c), w = s / a;
  return Vec3(-r * std::sin(w), r * std::cos(w), c) / a;
}

TEST(Rollout, QuadraticEndTangentIsExactOnALineAndSecondOrderOnAHelix) {
  // On a line (any spacing) the quadratic is the line: its tangent to round-off.
  const Vec3 x0(0.1, -0.2, 0.3), u = Vec3(1, 2, -2) / 3.0;
  EXPECT_LT((QuadraticEndTangent(x0, x0 + 0.07 * u, x0 + 0.19 * u, 0.07, 0.19) - u).norm(), 1e-14);
  // On a helix (curvature 2 1/m, torsion 1 1/m: r = 0.4, c = 0.2 m) sampled every h: the miss is
  // O(h^2) (the quadratic's error, h^2 / 3 of the third derivative, has a component off the
  // tangent); halving h quarters it.
  const double r = 0.4, c = 0.2;
  auto miss = [&](double h) {
    const Vec3 t = QuadraticEndTangent(HelixPoint(r, c, 0), HelixPoint(r, c, h),
                                       HelixPoint(r, c, 2 * h), h, 2 * h);
    return std::acos(std::min(1.0, t.dot(HelixTangent(r, c, 0))));
  };
  const double h = 0.09;  // the markers' spacing of the synthetic recordings
  EXPECT_GT(miss(h), 1e-4);  // measured 5.6e-3 rad; 1.4e-3 and 3.4e-4 at h / 2 and h / 4
  EXPECT_LT(miss(h), 0.05);
  for (double hh : {h, h / 2, h / 4}) {
    const double ratio = miss(hh) / miss(hh / 2);
    EXPECT_GT(ratio, 3.5) << hh;
    EXPECT_LT(ratio, 4.5) << hh;
  }
}

// Markers on a helix whose radius changes over time (12 markers 9 cm apart, 3 frames): with
// `grippers-per-frame` the clamp's tangent at every frame is that frame's quadratic's (to the
// helix's O(h^2)); with `grippers` (the first frames' tangent carried with the chord 0 -> 1)
// it is not, once the curvature near the end has changed.
TEST(Rollout, GrippersPerFrameFollowTheEndTangentOfEveryFrame) {
  const int M = 12;
  const double h = 0.09, c = 0.2;
  auto radius = [](int k) { return 0.4 + 0.15 * k; };
  std::vector<Eigen::Matrix3Xd> frames(3, Eigen::Matrix3Xd(3, M));
  for (int k = 0; k < 3; ++k)
    for (int m = 0; m < M; ++m) frames[k].col(m) = HelixPoint(radius(k), c, m * h);
  Scene scene = Cable();
  scene.rod.length = (M - 1) * h;
  auto worst_miss = [&](RolloutOptions o) {
    o.smooth_frames = 0;
    double worst_late = 0.0;
    o.gripper_frame = [&](int g, double t, const Eigen::Matrix3d& from_markers) {
      const int k = static_cast<int>(std::lround(t / kFrameInterval));
      if (g == 0 && k == 2) {
        // The helix's tangent at marker 0, of the quadratic through chords' arc lengths.
        const Vec3 exact = HelixTangent(radius(k), c, 0.0);
        worst_late = std::max(worst_late, std::acos(std::min(1.0, from_markers.col(2).dot(exact))));
      }
      return from_markers;
    };
    Rollout(scene, kFrameInterval, frames, o);  // the frames are read before the integration
    return worst_late;
  };
  RolloutOptions per_frame;
  per_frame.held_ends = RolloutOptions::HeldEnds::kGrippersPerFrame;
  per_frame.held_markers = {0, 1, 2, -3, -2, -1};
  RolloutOptions first_frames;
  first_frames.held_ends = RolloutOptions::HeldEnds::kGrippers;
  const double late_per_frame = worst_miss(per_frame), late_first = worst_miss(first_frames);
  // The quadratic's own miss at this spacing (as above, < 0.05 rad), where the first frames'
  // offset misses by what the curvature's change turns the end (measured 0.069 against 0.0014).
  EXPECT_LT(late_per_frame, 0.05);
  EXPECT_GT(late_first, 1.5 * late_per_frame);
  // Markers 2 and n-3 are read at every frame, so they must be held.
  RolloutOptions unheld = per_frame;
  unheld.held_markers = {0, 1, -2, -1};
  EXPECT_THROW(Rollout(scene, kFrameInterval, frames, unheld), std::invalid_argument);
}

// The rollout's held paths between frames (ResampleHeldPath): a marker moving on a quadratic in
// time is reproduced between the frames to round-off, a dropped frame included; on a cubic the
// error falls as the frame interval cubed; the recorded samples are kept exactly.
TEST(Rollout, HeldPathsFollowACubicBetweenFrames) {
  const Vec3 x0(0.1, -0.2, 0.3), v0(0.5, 1.0, -0.25), a0(-20.0, 8.0, 3.0), j0(400.0, -150.0, 90.0);
  auto quadratic = [&](double t) { return Vec3(x0 + v0 * t + a0 * t * t); };
  auto cubic = [&](double t) { return Vec3(quadratic(t) + j0 * t * t * t); };
  // Frames 0..20 every dt with frame 7 dropped.
  auto recorded = [](const std::function<Vec3(double)>& x, double dt) {
    TimeSeries p;
    for (int k = 0; k <= 20; ++k) {
      if (k == 7) continue;
      p.t.push_back(k * dt);
      p.a.push_back(x(k * dt));
    }
    return p;
  };
  TimeSeries p = recorded(quadratic, kFrameInterval);
  const TimeSeries raw = p;
  ResampleHeldPath(&p, kFrameInterval);
  ASSERT_EQ(p.t.size(), 20u * 10u + 1u);  // ten samples a frame, twenty over the dropped one
  for (size_t j = 0; j < p.t.size(); ++j) {
    EXPECT_NEAR(p.t[j], j * kFrameInterval / 10, 1e-15) << j;
    EXPECT_LT((p.a[j] - quadratic(p.t[j])).norm(), 1e-14) << j;
  }
  for (size_t k = 0; k < raw.t.size(); ++k) {  // the recorded samples themselves, exactly
    const size_t j = static_cast<size_t>(std::lround(raw.t[k] / kFrameInterval)) * 10;
    EXPECT_EQ(p.t[j], raw.t[k]) << k;
    EXPECT_EQ(p.a[j], raw.a[k]) << k;
  }
  // A cubic: the largest miss over the samples falls ~8-fold when the frame interval halves
  // (third order; linear interpolation between the frames is second order).
  double miss[2], linear_miss = 0.0;
  for (int r = 0; r < 2; ++r) {
    const double dt = kFrameInterval / (1 << r);
    const TimeSeries frames = recorded(cubic, dt);
    TimeSeries c = frames;
    ResampleHeldPath(&c, dt);
    miss[r] = 0.0;
    for (size_t j = 0; j < c.t.size(); ++j) {
      miss[r] = std::max(miss[r], (c.a[j] - cubic(c.t[j])).norm());
      // The frames interpolated linearly (what the engine would read without the resampling).
      const size_t k = std::upper_bound(frames.t.begin(), frames.t.end(), c.t[j]) - frames.t.begin();
      if (r == 0 && k > 0 && k < frames.t.size()) {
        const double w = (c.t[j] - frames.t[k - 1]) / (frames.t[k] - frames.t[k - 1]);
        const Vec3 line = (1 - w) * frames.a[k - 1] + w * frames.a[k];
        linear_miss = std::max(linear_miss, (line - cubic(c.t[j])).norm());
      }
    }
  }
  EXPECT_GT(miss[0], 1e-9);  // the cubic is not reproduced exactly (only a quadratic is)
  EXPECT_GT(miss[0] / miss[1], 6.0) << miss[0] << " " << miss[1];
  // The samples' velocities miss by D3 h0 h1 / 6 (one-sided: D3 h0 (h0 + h1) / 3), D3 = 6 |j0|
  // ~ 2.7e3 m/s^3 the third derivative: up to 0.08 m/s next to the dropped frame and at the
  // ends; the Hermite basis weighs it by at most 4 h / 27 (h up to 20 ms): ~2.4e-4 m (measured
  // 0.17 mm). The frames joined linearly miss by 7.2 mm.
  EXPECT_LT(miss[0], 3e-4) << miss[0];
  EXPECT_LT(miss[0], 0.05 * linear_miss) << miss[0] << " " << linear_miss;
  // Two samples: the line between them; one: left as it is.
  TimeSeries two;
  two.t = {0.0, kFrameInterval};
  two.a = {x0, Vec3(x0 + v0 * kFrameInterval)};
  ResampleHeldPath(&two, kFrameInterval);
  ASSERT_EQ(two.t.size(), 11u);
  EXPECT_LT((two.a[3] - (x0 + v0 * two.t[3])).norm(), 1e-15);
  TimeSeries one;
  one.t = {0.0};
  one.a = {x0};
  ResampleHeldPath(&one, kFrameInterval);
  EXPECT_EQ(one.t.size(), 1u);
}

// The second truth of the grippers: jaws spanning markers 0..1 and n-2..n-1 (the cable straight
// and rigid in them). The jaws model is that truth: at the true parameters it predicts the
// free markers far better than the pins, and its markers in the jaws are the held paths.
TEST(Rollout, JawsPredictARecordingOfTrueJaws) {
  const std::vector<Eigen::Matrix3Xd> frames =
      testing::JawsRecording(testing::HardGrippers(testing::HardMotion::kLoop, 1.0), 1.0, 0.0,
                             0.0, 3);
  Scene scene = Cable();
  DefaultTwistDamping(&scene.material);
  scene.dynamics->time_step = kFrameInterval;
  RolloutOptions jaws;  // the default
  ASSERT_EQ(jaws.held_ends, RolloutOptions::HeldEnds::kJaws);
  const RolloutResult r = Rollout(scene, kFrameInterval, frames, jaws);
  ASSERT_TRUE(r.ok) << r.reason;
  RolloutOptions pins;
  pins.held_ends = RolloutOptions::HeldEnds::kPinnedPairs;
  const RolloutResult p = Rollout(scene, kFrameInterval, frames, pins);
  ASSERT_TRUE(p.ok) << p.reason;
  EXPECT_LT(r.mae_predicted, 1e-3);  // measured 0.57 mm (pins 12.9 mm)
  EXPECT_GT(p.mae_predicted, 2.0 * r.mae_predicted);
  // Marker 0 (in the clamp's jaw) is its held path, smoothed (here to round-off: the path is
  // smooth), no rod vertex.
  for (size_t k = 0; k < frames.size(); k += 10)
    EXPECT_LT((r.predicted[k].col(0) - frames[k].col(0)).norm(), 1e-6) << k;
  // One jaw (marker n-2 not held): the far end is an end pin at marker n-1, as with the pins,
  // and marker n-2 is predicted.
  RolloutOptions one_jaw = jaws;
  one_jaw.held_markers = {0, 1, -1};
  const RolloutResult o = Rollout(scene, kFrameInterval, frames, one_jaw);
  ASSERT_TRUE(o.ok) << o.reason;
  EXPECT_FALSE(o.held[testing::kMarkers - 2]);
  EXPECT_TRUE(o.predicted.back().allFinite());
}

}  // namespace
}  // namespace rodfit
