// The haptic runtime driven as a careless hand and a glitching device drive it, through the C
// API (rodfit/runtime/rodfit_c.h): seeded random tool paths of 10^4 ticks — drags, pauses,
// reversals, jitter, jumps of up to 2 cm, orientation turns and jumps — for every bundled
// profile (data/profiles) in both modes (quasi-static with and without the held orientation,
// dynamic), and random pushes for the poke profile in both modes. Each run must never stall (no
// run of more than 200 consecutive ticks that are not RODFIT_OK), keep the force on the tool
// finite and, for a grasp, continuous: no tick changes it by more than EA max_tool_move, the
// force of one edge stretched by one tick's largest move (what the grasped vertex can do to
// its edges in a tick; the measured changes are printed, and are far below it in quasi-static
// mode, where the rod follows). It must never leave the rod more energy than the tool's work put
// in, keep a grasped rod within the strain limit (at most 10 % longer), and allocate nothing in
// its ticks. The tallies are printed.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/rodfit_c.h"
#include "rodfit/runtime/runtime.h"
#include "runtime/allocation_counter.h"

namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

constexpr int kTicks = 10000;
constexpr int kMaxFailedRun = 200;      // consecutive ticks that are not RODFIT_OK, at most
constexpr double kMaxJump = 0.02;       // [m] the largest jump of the tool
constexpr double kMaxDragMove = 4e-4;   // [m per tick] a drag's largest move (0.4 m/s)
constexpr double kMaxJitter = 1e-4;     // [m] a jittering device's largest offset
constexpr double kPathRadius = 0.03;    // [m] the tool stays this close to where it took hold
constexpr double kMaxTurn = 0.6;        // [rad] ... and this close to its first orientation
constexpr double kMaxStrain = 0.1;      // RuntimeOptions::max_strain's default

// Uniform in [0, 1) from the 53 high bits: the same numbers on every standard library (the
// generator's output is specified by the standard; its distributions are not).
class Random {
 public:
  explicit Random(uint64_t seed) : engine_(seed) {}
  double Uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  int Ticks(int lo, int hi) { return lo + static_cast<int>(Uniform() * (hi - lo)); }
  Vec3 Direction() {
    Vec3 d;
    do {
      d = Vec3(Uniform(-1, 1), Uniform(-1, 1), Uniform(-1, 1));
    } while (d.squaredNorm() > 1.0 || d.squaredNorm() < 1e-6);
    return d.normalized();
  }

 private:
  std::mt19937_64 engine_;
};

// A tool path: segments of random kind and length, the position kept within kPathRadius of
// `home` and within 0.95 of the grasp's reach from the clamp (beyond it ticks are held at the
// strain limit on purpose, which the strain test covers), the orientation within kMaxTurn.
class ToolPath {
 public:
  ToolPath(uint64_t seed, const Vec3& home, const Vec3& clamp, double reach)
      : random_(seed), home_(home), clamp_(clamp), reach_(reach), position_(home) {}

  void Next() {
    if (left_ == 0) NewSegment();
    --left_;
    position_ += velocity_;
    offset_ = jitter_ > 0.0 ? Vec3(random_.Uniform(0.0, jitter_) * random_.Direction())
                            : Vec3::Zero();
    // Reflected back inside its region.
    Vec3 from_home = position_ - home_;
    if (from_home.norm() > kPathRadius) {
      position_ = home_ + kPathRadius * from_home.normalized();
      velocity_ = -velocity_;
    }
    Vec3 from_clamp = position_ - clamp_;
    if (from_clamp.norm() > 0.95 * reach_) {
      position_ = clamp_ + 0.95 * reach_ * from_clamp.normalized();
      velocity_ = -velocity_;
    }
    orientation_ = Eigen::AngleAxisd(spin_, spin_axis_) * orientation_;
    if (Eigen::AngleAxisd(orientation_).angle() > kMaxTurn) spin_ = -spin_;
    ++tick_;
  }
  Vec3 position() const { return position_ + offset_; }
  const Mat3& orientation() const { return orientation_; }
  // Poke: a force whose magnitude walks within [0, max] and whose direction turns; jumps too.
  Vec3 Force(double max) {
    if (tick_ % 97 == 0) force_rate_ = random_.Uniform(-0.01, 0.01) * max * random_.Direction();
    if (random_.Uniform() < 0.002) force_ = random_.Uniform(0.0, max) * random_.Direction();
    force_ += force_rate_;
    if (force_.norm() > max) {
      force_ *= max / force_.norm();
      force_rate_ = -force_rate_;
    }
    return force_;
  }
  int jumps() const { return jumps_; }

 private:
  void NewSegment() {
    const double u = random_.Uniform();
    jitter_ = 0.0;
    if (u < 0.35) {  // drag
      velocity_ = random_.Uniform(0.0, kMaxDragMove) * random_.Direction();
      left_ = random_.Ticks(20, 400);
    } else if (u < 0.55) {  // pause
      velocity_.setZero();
      left_ = random_.Ticks(10, 300);
    } else if (u < 0.70) {  // reversal
      velocity_ = velocity_.isZero() ? random_.Uniform(0.0, kMaxDragMove) * random_.Direction()
                                     : Vec3(-velocity_);
      left_ = random_.Ticks(20, 300);
    } else if (u < 0.85) {  // jitter about a still tool
      velocity_.setZero();
      jitter_ = random_.Uniform(0.0, kMaxJitter);
      left_ = random_.Ticks(20, 200);
    } else {  // a jump (a lost tracking frame), then held still
      position_ += random_.Uniform(0.0, kMaxJump) * random_.Direction();
      orientation_ = Eigen::AngleAxisd(random_.Uniform(0.0, 0.5), random_.Direction()) *
                     orientation_;
      velocity_.setZero();
      left_ = random_.Ticks(50, 300);
      ++jumps_;
    }
    spin_ = random_.Uniform(-0.01, 0.01);  // [rad per tick]
    spin_axis_ = random_.Direction();
  }

  Random random_;
  Vec3 home_, clamp_;
  double reach_;
  Vec3 position_, velocity_ = Vec3::Zero(), offset_ = Vec3::Zero();
  Mat3 orientation_ = Mat3::Identity();
  double spin_ = 0.0, jitter_ = 0.0;
  Vec3 spin_axis_ = Vec3::UnitX();
  Vec3 force_ = Vec3::Zero(), force_rate_ = Vec3::Zero();
  int left_ = 0, tick_ = 0, jumps_ = 0;
};

struct PathRun {
  const char* profile;
  double tool_s;  // [m]
  int mode;       // RODFIT_MODE_*
  int tool;       // RODFIT_TOOL_*
  bool oriented;
  uint64_t seed;
};

void PrintTo(const PathRun& r, std::ostream* os) {
  *os << r.profile << (r.mode == RODFIT_MODE_DYNAMIC ? " dynamic" : " quasi-static")
      << (r.oriented ? " oriented" : "") << (r.tool == RODFIT_TOOL_POKE ? " poke" : " grasp")
      << ", seed " << r.seed;
}

std::string RunName(const ::testing::TestParamInfo<PathRun>& info) {
  std::string name = info.param.profile;
  name = name.substr(0, name.find('.'));
  name += info.param.mode == RODFIT_MODE_DYNAMIC ? "_dynamic" : "_quasi_static";
  name += info.param.oriented ? "_oriented" : "";
  return name + (info.param.tool == RODFIT_TOOL_POKE ? "_poke" : "_grasp");
}

class ToolPathTorture : public ::testing::TestWithParam<PathRun> {};

TEST_P(ToolPathTorture, NeverStallsNorJumpsNorGainsEnergy) {
  const PathRun run = GetParam();
  const std::string path = std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" + run.profile;
  const rodfit::Profile profile = rodfit::LoadProfile(path);
  const double length = profile.scene.rod.length;
  // The largest change of the grasp's force in one tick (see the file comment) [N].
  const double force_jump_bound =
      profile.scene.material.stretch_stiffness * rodfit::RuntimeOptions().max_tool_move;
  rodfit_options options;
  rodfit_default_options(&options);
  options.mode = run.mode;
  options.tool = run.tool;
  options.tool_s = run.tool_s;
  options.hold_orientation = run.oriented ? 1 : 0;
  char error[512];
  rodfit_runtime* rt = nullptr;
  ASSERT_EQ(rodfit_create(path.c_str(), &options, nullptr, nullptr, 0, &rt, error, sizeof(error)),
            RODFIT_OK)
      << error;
  const int n = rodfit_num_vertices(rt);
  std::vector<double> shape(3 * n);
  ASSERT_EQ(rodfit_get_shape(rt, shape.data(), shape.size()), RODFIT_OK);
  const Vec3 clamp(shape[0], shape[1], shape[2]);
  Vec3 home;
  ASSERT_EQ(rodfit_get_tool_position(rt, home.data()), RODFIT_OK);
  const bool poke = run.tool == RODFIT_TOOL_POKE;
  ToolPath tool_path(run.seed, home, clamp, (1.0 + kMaxStrain) * run.tool_s);
  // A push up to the bowel's weight (0.66 N) and beyond it: 1 N.
  const double max_push = 1.0;

  // What the loop reads back each tick, into buffers sized before it.
  Vec3 force = Vec3::Zero(), torque = Vec3::Zero(), at = home, push = Vec3::Zero();
  Mat3 held = Mat3::Identity();
  double potential = 0.0, kinetic = 0.0;
  ASSERT_EQ(rodfit_get_tool_force(rt, force.data(), torque.data()), RODFIT_OK);
  ASSERT_EQ(rodfit_get_energy(rt, &potential, &kinetic), RODFIT_OK);
  const double e0 = potential + kinetic;
  // Tallies.
  int ok = 0, budget = 0, not_converged = 0, strain = 0, refused = 0, other = 0;
  int failed_run = 0, longest_failed_run = 0;
  bool finite = true;
  double work = 0.0;            // [J] the tool's on the rod
  double work_slack = 0.0;      // [J] the trapezoid rule's bound, sum of |dF| |dx| / 2
  double least_margin = 1e300;  // [J] min over ticks of W + slack - (E - E0)
  double largest_jump = 0.0;    // [N] max |F_k - F_k-1|
  double largest_move = 0.0;    // [m] max |x_k - x_k-1| of the tool's point
  double longest_rod = 0.0;     // [m]
  std::vector<double> held_data(9);
  rodfit_test::StartCountingAllocations();
  for (int k = 1; k <= kTicks; ++k) {
    tool_path.Next();
    if (poke) {
      push = tool_path.Force(max_push);
      rodfit_set_tool_force(rt, push.data());
    } else {
      const Vec3 p = tool_path.position();
      rodfit_set_tool_position(rt, p.data());
      Eigen::Matrix<double, 3, 3, Eigen::RowMajor> r = tool_path.orientation();
      rodfit_set_tool_orientation(rt, r.data());
    }
    rodfit_step_info info;
    const rodfit_status status = rodfit_step(rt, &info);
    switch (status) {
      case RODFIT_OK: ++ok; break;
      case RODFIT_TIME_BUDGET: ++budget; break;
      case RODFIT_NOT_CONVERGED: ++not_converged; break;
      case RODFIT_STRAIN_LIMIT: ++strain; break;
      case RODFIT_TOOL_REFUSED: ++refused; break;
      default: ++other; break;
    }
    failed_run = status == RODFIT_OK ? 0 : failed_run + 1;
    longest_failed_run = std::max(longest_failed_run, failed_run);
    const Vec3 last_force = force, last_torque = torque, last_at = at;
    const Mat3 last_held = held;
    rodfit_get_tool_force(rt, force.data(), torque.data());
    rodfit_get_tool_position(rt, at.data());
    rodfit_get_tool_orientation(rt, held_data.data());
    for (int e = 0; e < 9; ++e) held(e / 3, e % 3) = held_data[e];
    rodfit_get_energy(rt, &potential, &kinetic);
    rodfit_get_shape(rt, shape.data(), shape.size());
    finite = finite && force.allFinite() && torque.allFinite() && std::isfinite(potential);
    // The tool's work on the rod: a grasp's -F . dx (trapezoid) and -T . dphi; a poke's dead
    // force f . dx (Energy() counts a poke's -f . x: the rod's own energy adds it back).
    const Vec3 dx = at - last_at;
    if (poke) {
      work += (-force).dot(dx);  // the force applied in this tick: minus the one on the tool
    } else {
      work -= 0.5 * (force + last_force).dot(dx);
      work_slack += 0.5 * (force - last_force).norm() * dx.norm();
      const Eigen::AngleAxisd turn(held * last_held.transpose());
      work -= 0.5 * (torque + last_torque).dot(turn.angle() * turn.axis());
      work_slack += 0.5 * (torque - last_torque).norm() * turn.angle();
      largest_jump = std::max(largest_jump, (force - last_force).norm());
    }
    largest_move = std::max(largest_move, dx.norm());
    const double energy = potential + (poke ? (-force).dot(at) : 0.0) + kinetic;
    least_margin = std::min(least_margin, work + work_slack - (energy - e0));
    double rod = 0.0;
    for (int i = 1; i < n; ++i)
      rod += (Eigen::Map<const Vec3>(&shape[3 * i]) - Eigen::Map<const Vec3>(&shape[3 * i - 3]))
                 .norm();
    longest_rod = std::max(longest_rod, rod);
  }
  const long allocations = rodfit_test::StopCountingAllocations();
  std::printf(
      "%s %s%s%s, %d ticks (%d jumps): %d ok, %d over the time budget, %d not converged, %d at "
      "the strain limit, %d refused; longest run of failed ticks %d; largest |dF| %.3g N per "
      "tick (bound %.3g N), largest tool-point move %.3g mm; energy margin W - (E - E0) >= %.3g "
      "J (work %.3g J); longest rod %.5f L; %ld allocations\n",
      run.profile, run.mode == RODFIT_MODE_DYNAMIC ? "dynamic" : "quasi-static",
      run.oriented ? " oriented" : "", poke ? " poke" : " grasp", kTicks, tool_path.jumps(), ok,
      budget, not_converged, strain, refused, longest_failed_run, largest_jump,
      poke ? 0.0 : force_jump_bound,
      1e3 * largest_move, least_margin, work, longest_rod / length, allocations);
  EXPECT_EQ(other, 0);
  EXPECT_EQ(refused, 0);  // the path's inputs are all valid
  EXPECT_LE(longest_failed_run, kMaxFailedRun);
  EXPECT_TRUE(finite);
  EXPECT_GE(least_margin, -1e-12 * (std::abs(e0) + std::abs(work)));
  EXPECT_EQ(allocations, 0);
  if (!poke) {
    EXPECT_LE(largest_jump, force_jump_bound);
    // The strain limit is the grasp's (a poke's force is only refused above max_strain EA: an
    // undamped rod swinging under a sudden push may stretch further for a moment).
    EXPECT_LE(longest_rod, (1.0 + kMaxStrain) * length);
  }
  rodfit_destroy(rt);
}

INSTANTIATE_TEST_SUITE_P(
    Bundled, ToolPathTorture,
    ::testing::Values(
        PathRun{"suture.json", 0.2, RODFIT_MODE_QUASI_STATIC, RODFIT_TOOL_GRASP, false, 1},
        PathRun{"suture.json", 0.2, RODFIT_MODE_QUASI_STATIC, RODFIT_TOOL_GRASP, true, 2},
        PathRun{"suture.json", 0.2, RODFIT_MODE_DYNAMIC, RODFIT_TOOL_GRASP, false, 3},
        PathRun{"bowel_drag.json", 0.1, RODFIT_MODE_QUASI_STATIC, RODFIT_TOOL_GRASP, false, 4},
        PathRun{"bowel_drag.json", 0.1, RODFIT_MODE_QUASI_STATIC, RODFIT_TOOL_GRASP, true, 5},
        PathRun{"bowel_drag.json", 0.1, RODFIT_MODE_DYNAMIC, RODFIT_TOOL_GRASP, false, 6},
        PathRun{"bowel_poke.json", 0.075, RODFIT_MODE_QUASI_STATIC, RODFIT_TOOL_GRASP, false, 7},
        PathRun{"bowel_poke.json", 0.075, RODFIT_MODE_QUASI_STATIC, RODFIT_TOOL_GRASP, true, 8},
        PathRun{"bowel_poke.json", 0.075, RODFIT_MODE_DYNAMIC, RODFIT_TOOL_GRASP, false, 9},
        PathRun{"bowel_poke.json", 0.075, RODFIT_MODE_QUASI_STATIC, RODFIT_TOOL_POKE, false, 10},
        PathRun{"bowel_poke.json", 0.075, RODFIT_MODE_DYNAMIC, RODFIT_TOOL_POKE, false, 11}),
    RunName);

}  // namespace
