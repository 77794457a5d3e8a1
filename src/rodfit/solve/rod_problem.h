// What every Newton problem over a rod's state shares (newton_minimizer.h): the iterates (the
// current state, a trial and the previous one, with their frames), the retraction (ApplyStep:
// edge-wise, reference frames transported in time), the caps on a step (the turn of a tangent,
// the change of an edge's strain), the step's size against its tolerance, the scaled residual's
// weights, the energy's round-off and the first diagonal shift. The statics, each implicit time
// step and the runtime's ticks derive from it and add their merit and residual.
#pragma once

#include "rodfit/model/rod.h"
#include "rodfit/solve/newton_minimizer.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {

/// Largest turn [rad] of any edge tangent in one step: beyond it the edge-wise retraction is far
/// from the linearisation, and the step is shortened (StaticsOptions::max_rotation_per_step
/// defaults to it).
inline constexpr double kMaxTurnPerStep = 0.5;
/// Largest change of an edge's strain in one step: on a fine rod whose edges are soft in stretch
/// against their bending (EA l^2 / EI << 1) a full step would crumple them.
inline constexpr double kMaxStrainStep = 0.1;
/// Relative round-off of a rod's energy: an Armijo test between two values equal to this
/// precision (of the energy and of the loads' work over the rod) is decided by noise.
inline constexpr double kEnergyRoundOff = 1e-13;
/// The first diagonal shift for an indefinite rod matrix, as a fraction of its softest stiffness
/// min(B1, B2, GJ) / l^3 (not of the diagonal, which EA / l dominates: a shift of even 1e-10 of
/// that would swamp the bending and stall Newton on a stiff, fine rod).
inline constexpr double kShiftOfSoftest = 1e-6;

/// The rod's Newton matrix's round-off floor on the residual [N, scaled]: the stretch forces are
/// EA (|e| / l - 1) with |e| known to ~eps, so each carries ~eps EA; a vertex sums two and the
/// scaled norm multiplies by up to L / l (the weights' largest).
double ResidualFloor(const RodModel& model, const VecX& weights);

class RodNewtonProblem : public NewtonProblem {
 public:
  /// `step_tolerance`: a step moving no vertex by more than step_tolerance * step_length [m]
  /// and no twist angle by more than step_tolerance [rad] is within tolerance.
  RodNewtonProblem(const RodModel& model, double step_tolerance, double step_length);

  /// The iterates. current() is where the minimizer stands (set it before Minimize, and mark
  /// its frames stale with CurrentChanged()).
  RodState& current() { return current_; }
  const RodState& current() const { return current_; }
  RodState& trial() { return trial_; }
  RodFrames& frames() { return frames_; }
  void CurrentChanged() { frames_valid_ = false; }
  /// Frames of the current iterate, computed when stale.
  const RodFrames& CurrentFrames();
  const RodFrames& TrialFrames();
  const RodModel& model() const { return model_; }
  /// Retractions keep the twist angles at zero twist (SetZeroTwist): the twist is eliminated.
  void set_zero_twist(bool on) { zero_twist_ = on; }
  void set_max_turn(double radians) { max_turn_ = radians; }
  /// The sum of alpha * step of the steps accepted since the last call (the runtime's
  /// correction), kept when `track` is set.
  void set_track_steps(VecX* sum) { step_sum_ = sum; }

  int NumDofs() const override { return model_.num_free_dofs(); }
  bool Retract(const VecX& step, double alpha) override;
  void AcceptTrial() override;
  void RestorePrevious() override;
  StepCaps Caps(const VecX& step) override;
  RelativeStep Measure(const VecX& step) override;
  double LastMove() override;
  double StagnationMove() override;
  const VecX& NormWeights() override { return weights_; }
  double EnergyNoise(double energy) override;
  double ShiftBase() override;
  double Length() override { return model_.length(); }

 protected:
  const RodModel& model_;
  VecX weights_;
  double step_tolerance_;
  double step_length_;

 private:
  RodState current_, trial_, previous_;
  RodFrames frames_, trial_frames_, previous_frames_;
  bool frames_valid_ = false, trial_frames_valid_ = false, previous_frames_valid_ = false;
  bool zero_twist_ = false;
  double max_turn_ = kMaxTurnPerStep;
  // The last retraction's step and length, and the running sum (set_track_steps).
  const VecX* retract_step_ = nullptr;
  double retract_alpha_ = 0.0;
  VecX* step_sum_ = nullptr;
  double accepted_alpha_ = 0.0;
  const VecX* accepted_step_ = nullptr;
};

}  // namespace rodfit
