// The shared parts of the rod's Newton problems (rod_problem.h).
#include "rodfit/solve/rod_problem.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace rodfit {

double ResidualFloor(const RodModel& model, const VecX& weights) {
  const double max_weight = weights.size() ? weights.maxCoeff() : 1.0;
  return 64.0 * std::numeric_limits<double>::epsilon() * model.material().stretch_stiffness *
         max_weight;
}

RodNewtonProblem::RodNewtonProblem(const RodModel& model, double step_tolerance,
                                   double step_length)
    : model_(model),
      weights_(GradientNormWeights(model)),
      step_tolerance_(step_tolerance),
      step_length_(step_length) {
  // Every iterate and frame list at its size now: the iterations then allocate nothing (the
  // runtime's ticks rely on it).
  current_ = model.StraightState();
  trial_ = current_;
  previous_ = current_;
  ComputeRodFrames(model, current_, &frames_);
  trial_frames_ = frames_;
  previous_frames_ = frames_;
}

const RodFrames& RodNewtonProblem::CurrentFrames() {
  if (!frames_valid_) ComputeRodFrames(model_, current_, &frames_);
  frames_valid_ = true;
  return frames_;
}

const RodFrames& RodNewtonProblem::TrialFrames() {
  if (!trial_frames_valid_) ComputeRodFrames(model_, trial_, &trial_frames_);
  trial_frames_valid_ = true;
  return trial_frames_;
}

bool RodNewtonProblem::Retract(const VecX& step, double alpha) {
  trial_frames_valid_ = false;
  if (!ApplyStep(model_, current_, step, alpha, &trial_)) return false;
  if (zero_twist_) SetZeroTwist(model_, &trial_);
  retract_step_ = &step;
  retract_alpha_ = alpha;
  return true;
}

void RodNewtonProblem::AcceptTrial() {
  // Swaps only: no copy, no allocation. The old current is kept for RestorePrevious.
  std::swap(previous_, current_);
  std::swap(current_, trial_);
  std::swap(previous_frames_, frames_);
  std::swap(frames_, trial_frames_);
  previous_frames_valid_ = frames_valid_;
  frames_valid_ = trial_frames_valid_;
  trial_frames_valid_ = false;
  accepted_step_ = retract_step_;
  accepted_alpha_ = retract_alpha_;
  if (step_sum_ && accepted_step_) *step_sum_ += accepted_alpha_ * *accepted_step_;
}

void RodNewtonProblem::RestorePrevious() {
  std::swap(previous_, current_);
  std::swap(previous_frames_, frames_);
  std::swap(previous_frames_valid_, frames_valid_);
  if (step_sum_ && accepted_step_) *step_sum_ -= accepted_alpha_ * *accepted_step_;
  accepted_step_ = nullptr;
}

StepCaps RodNewtonProblem::Caps(const VecX& step) {
  const StepTurnStrain ts = MaxTurnAndStrainChange(model_, current_, step);
  StepCaps caps;
  caps.turn = ts.turn;
  if (caps.turn > max_turn_) caps.alpha = max_turn_ / caps.turn;
  if (caps.alpha * ts.strain > kMaxStrainStep) caps.alpha = kMaxStrainStep / ts.strain;
  return caps;
}

// The largest position and angle entries of a step (held dofs skipped by their zero weight),
// over their tolerances: blocks [x_i, theta_i] of four dofs (RodModel::VertexDof, TwistDof), the
// maxima in registers and no branch per entry.
RelativeStep RodNewtonProblem::Measure(const VecX& step) {
  double x = 0.0, theta = 0.0;
  const int m = static_cast<int>(step.size());
  const double* s = step.data();
  const double* w = weights_.data();
  auto held0 = [&](int k) { return w[k] == 0.0 ? 0.0 : std::abs(s[k]); };
  for (int k = 0; k + 3 < m; k += 4) {
    x = std::max({x, held0(k), held0(k + 1), held0(k + 2)});
    theta = std::max(theta, held0(k + 3));
  }
  return {x / (step_tolerance_ * step_length_), theta / step_tolerance_};
}

double RodNewtonProblem::LastMove() {
  if (!accepted_step_) return std::numeric_limits<double>::infinity();
  return (current_.x - previous_.x).colwise().norm().maxCoeff();
}

double RodNewtonProblem::StagnationMove() {
  return NewtonMinimizer::kFloorRelaxation * step_tolerance_ * step_length_;
}

double RodNewtonProblem::EnergyNoise(double energy) {
  return kEnergyRoundOff * (std::abs(energy) + model_.force_scale() * model_.length());
}

double RodNewtonProblem::ShiftBase() {
  const Material& m = model_.material();
  const double l = model_.min_rest_edge_length();
  return kShiftOfSoftest * std::min({m.B1(), m.B2(), m.twist_stiffness}) / (l * l * l);
}

}  // namespace rodfit
