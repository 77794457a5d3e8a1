// Fit benchmark: wall time of the identification of B1 and B2 from the suture
// cantilever protocol (calibration/suture_cantilever) against the number of load cases and of
// markers per case, 50 segments, starts three times too soft. The synthetic markers are solved
// and noised once in the setup, outside the timed loop; every timed iteration is a complete Fit()
// from the same start (Fit keeps no warm start between calls). Counters: Levenberg–Marquardt
// iterations, forward solves, and where the time goes as fractions of the wall time: forward
// solves, sensitivities (Jacobian), observation models, and the remainder (Ceres, covariance,
// identifiability). With 2 threads the first three are summed over both threads, so they can add
// up to more than 1 and the remainder can be negative.
// Target: the 4-case recipe (50 segments, 2 parameters, 40 markers) in <= 0.1 s on one core.
// BM_FitSequences: the motion fit of data/suture_swing_fit (bending stiffness and air drag from
// 4 markers at 100 Hz over a 0.25 s swing, 10 edges, 100 BDF2 steps per run), from its starts.
// BM_FitRecording500Frames: the held-out protocol's fit (rollout --fit): bending stiffness and
// air drag of a 1 m cable from one 5 s recording of 12 markers at 100 Hz (500 frames, 1 mm
// noise, 2 % dropped; two grippers moving it: solve/mocap_fixture.h), rolled out at the
// protocol's 10 ms step on 44 edges, from starts 3x off. Target: a 500-frame fit under 10 s.
// BM_FitPixelSequences: the same fit to one camera's centre-line pixels instead (10 per frame at
// 100 Hz, 0.5 px of noise; closest-point residuals).
// Run: build/bench_fit [--benchmark_filter=...]; Release build.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/pipeline/sequence_input.h"
#include "rodfit/fit/motion_fit.h"
#include "rodfit/solve/case_dynamics.h"
#include "rodfit/solve/rollout.h"
#include "rodfit/solve/statics.h"
#include "rodfit/vision/camera_file.h"
#include "solve/mocap_fixture.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The recipe's suture (calibration/suture_cantilever/protocol.yaml): braided USP 2, 0.2 m.
FitInput Suture() {
  FitInput in;
  in.rod.length = 0.2;
  in.rod.segments = 50;
  in.rod.radius = 2.5e-4;
  in.rod.linear_density = 2.24e-4;
  in.material.bend_stiffness = 9.2e-6;
  in.material.bend_stiffness_2 = 1.1e-5;
  in.material.twist_stiffness = 6.8e-6;
  in.material.stretch_stiffness = 589;
  in.gravity = Vec3(0, 0, -9.81);
  return in;
}

LoadCase Clamped(const std::string& name, const Vec3& tangent, const Vec3& normal,
                 const Vec3& tip_force = Vec3::Zero()) {
  LoadCase c;
  c.name = name;
  c.clamp.tangent = tangent;
  c.clamp.normal = normal;
  c.tip_force = tip_force;
  return c;
}

// Up to eight clamp orientations and loads. The first four are the recipe's cases, `pulled` first
// so that a single case already bends the suture about both axes (gravity about d2, the sideways
// pull about d1) and both stiffnesses are identifiable at every case count.
std::vector<LoadCase> ProtocolCases() {
  const double c30 = std::cos(kPi / 6), s30 = std::sin(kPi / 6);
  const double c20 = std::cos(kPi / 9), s20 = std::sin(kPi / 9);
  const double r2 = std::sqrt(0.5);
  return {
      Clamped("pulled", Vec3(1, 0, 0), Vec3(0, 0, 1), Vec3(0, 1.5e-4, 0)),
      Clamped("rolled", Vec3(1, 0, 0), Vec3(0, 1, 0)),
      Clamped("flat", Vec3(1, 0, 0), Vec3(0, 0, 1)),
      Clamped("up30", Vec3(c30, 0, s30), Vec3(-s30, 0, c30)),
      Clamped("down20", Vec3(c20, 0, -s20), Vec3(s20, 0, c20)),
      Clamped("rolled_up30", Vec3(c30, 0, s30), Vec3(0, 1, 0)),
      Clamped("rolled45", Vec3(1, 0, 0), Vec3(0, r2, r2)),
      Clamped("pulled_up", Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1.0e-4)),
  };
}

// `num_cases` cases with `markers` 3-D markers each, evenly spaced with the last at the tip,
// Gaussian noise of 0.3 mm (the recipe's sigma), fixed seed; B1 and B2 fitted from 3e-6.
FitInput Protocol(int num_cases, int markers, std::string* error) {
  FitInput in = Suture();
  const double sigma = 3.0e-4;
  std::mt19937 rng(20240601);
  std::normal_distribution<double> normal(0.0, 1.0);
  const std::vector<LoadCase> all = ProtocolCases();
  for (int c = 0; c < num_cases; ++c) {
    const LoadCase& load = all[c % all.size()];
    const RodModel model(in.rod, in.material, in.gravity, load);
    RodState state = model.StraightState();
    const StaticsSummary summary = SolveStatics(model, StaticsOptions(), &state);
    if (!summary.converged) *error = load.name + ": " + summary.BriefReport();
    const std::vector<double> arc = VertexArcLengths(model);
    const double l = in.rod.length / in.rod.segments;
    std::vector<Marker3d> observed;
    for (int k = 1; k <= markers; ++k) {
      Marker3d m;
      m.s = in.rod.length * k / markers;
      const int e = std::min(static_cast<int>(m.s / l), in.rod.segments - 1);
      const double a = m.s / l - e;
      m.p_world = (1 - a) * state.x.col(e) + a * state.x.col(e + 1) +
                  sigma * Vec3(normal(rng), normal(rng), normal(rng));
      observed.push_back(m);
    }
    FitCase fc;
    fc.load_case = load;
    fc.measurements.push_back(MakeShapeMeasurement("markers3d", "markers3d " + load.name,
                                                   Markers3dObservation(arc, observed, sigma)));
    in.cases.push_back(fc);
  }
  for (const char* name : {"bend_stiffness", "bend_stiffness_2"}) {
    Parameter p;
    p.name = name;
    p.value = 3.0e-6;
    p.fit = true;
    p.min = 1.0e-8;
    p.max = 1.0e-3;
    in.parameters.push_back(p);
  }
  in.parameters.push_back({"twist_stiffness", in.material.twist_stiffness, false, {}, {}});
  in.parameters.push_back({"stretch_stiffness", in.material.stretch_stiffness, false, {}, {}});
  in.material.bend_stiffness = 3.0e-6;  // the starts
  in.material.bend_stiffness_2 = 3.0e-6;
  return in;
}

// Runs the timed loop and sets the counters (averages over the timed fits).
void TimeFit(benchmark::State& st, const FitInput& in, int threads) {
  FitOptions options;
  options.num_threads = threads;
  FitResult r;
  double seconds = 0, solve = 0, jacobian = 0, observation = 0;
  int fits = 0;
  for (auto _ : st) {
    r = Fit(in, options);
    benchmark::DoNotOptimize(r.final_cost);
    seconds += r.seconds;
    solve += r.solve_seconds;
    jacobian += r.jacobian_seconds;
    observation += r.observation_seconds;
    ++fits;
  }
  if (!r.success) {
    st.SkipWithError(("fit failed: " + r.message).c_str());
    return;
  }
  for (const Parameter& p : r.parameters) {
    if (p.fit && !p.identifiable) {
      st.SkipWithError((p.name + " not identifiable: " + p.reason).c_str());
      return;
    }
  }
  st.counters["iterations"] = r.iterations;
  st.counters["forward_solves"] = r.forward_solves;
  st.counters["solve"] = solve / seconds;
  st.counters["jacobian"] = jacobian / seconds;
  st.counters["observe"] = observation / seconds;
  st.counters["rest"] = 1.0 - (solve + jacobian + observation) / seconds;
  st.counters["fit_ms"] = 1e3 * seconds / std::max(1, fits);
}

// Args: cases, markers per case, threads.
void BM_FitProtocol(benchmark::State& st) {
  std::string error;
  const FitInput in =
      Protocol(static_cast<int>(st.range(0)), static_cast<int>(st.range(1)), &error);
  if (!error.empty()) {
    st.SkipWithError(error.c_str());
    return;
  }
  TimeFit(st, in, static_cast<int>(st.range(2)));
}
BENCHMARK(BM_FitProtocol)
    ->ArgNames({"cases", "markers", "threads"})
    ->ArgsProduct({{1, 2, 4, 8}, {5, 10, 40}, {1}})
    ->ArgsProduct({{4}, {5, 10, 40}, {2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The recipe itself, read from calibration/suture_cantilever/experiment.yaml: 4 cases, each
// 10 markers in 3-D and the same 10 in two cameras (40 markers in all, 200 residuals). The
// source folder is found from this file's path (CMake compiles it by its absolute path).
void BM_FitRecipe(benchmark::State& st) {
  const std::filesystem::path recipe = std::filesystem::path(__FILE__).parent_path() / ".." /
                                       ".." / "calibration" / "suture_cantilever" /
                                       "experiment.yaml";
  if (!std::filesystem::is_regular_file(recipe)) {
    st.SkipWithError(("no recipe at " + recipe.string()).c_str());
    return;
  }
  const Experiment experiment = LoadExperiment(recipe.lexically_normal().string());
  const FitInput in = BuildFitInput(experiment);
  TimeFit(st, in, static_cast<int>(st.range(0)));
}
BENCHMARK(BM_FitRecipe)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// A moving experiment (data/suture_swing_fit/experiment.yaml, read once): every timed iteration
// is a complete FitSequences from the starts. Counters: iterations and runs of the case (each
// with its sensitivities).
void BM_FitSequences(benchmark::State& st) {
  const std::string path = std::string(RODFIT_SOURCE_DIR) + "/data/suture_swing_fit/experiment.yaml";
  if (!std::filesystem::is_regular_file(path)) {
    st.SkipWithError(("no example at " + path).c_str());
    return;
  }
  const Experiment experiment = LoadExperiment(path);
  const SequenceInput input = BuildSequenceInput(experiment);
  const std::vector<std::string> names = FittedNames(experiment);
  const MotionFitOptions options = SequenceFitOptionsOf(experiment, names);
  MotionFitResult r;
  for (auto _ : st) {
    r = FitSequences(experiment.scene, input.sequences, names, experiment.statics, options);
    benchmark::DoNotOptimize(r.values.data());
  }
  if (!r.converged) st.SkipWithError(("the fit did not converge: " + r.message).c_str());
  st.counters["iterations"] = r.iterations;
  st.counters["runs"] = r.evaluations;
}
BENCHMARK(BM_FitSequences)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FitRecording500Frames(benchmark::State& st) {
  const std::vector<Eigen::Matrix3Xd> frames = testing::Recording(5.0, 1e-3, 0.02, 1);
  Scene start = testing::Cable();
  start.dynamics->time_step = testing::kFrameInterval;
  start.material.bend_stiffness *= 3.0;
  start.material.damping *= 3.0;
  DefaultTwistDamping(&start.material);  // as `rodfit rollout` does
  MotionFitOptions options;
  options.marker_sigma = 1e-3;
  MotionFitResult r;
  for (auto _ : st) {
    r = FitMotion(start, {{"", testing::kFrameInterval, frames}}, {"bend_stiffness", "damping"},
                  RolloutOptions(), StaticsOptions(), options);
    benchmark::DoNotOptimize(r.values.data());
  }
  if (!r.converged) st.SkipWithError(("the fit did not converge: " + r.message).c_str());
  st.counters["frames"] = static_cast<double>(frames.size());
  st.counters["rollouts"] = r.evaluations;
  st.counters["bend_stiffness_over_truth"] = r.values[0] / testing::Cable().material.bend_stiffness;
  st.counters["damping_over_truth"] = r.values[1] / testing::Cable().material.damping;
  st.counters["error_mm"] = 1e3 * r.error_fitted;
}
BENCHMARK(BM_FitRecording500Frames)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

// The held-out protocol's training set: 6 recordings x 500 frames (5 s at 100 Hz, 12 markers,
// 1 mm noise, 2 % dropped) of the cable between two grippers — the gentle motion of Recording
// with two noise seeds and the four hard motions (whip, pull, loop, fold) — bending stiffness and
// drag fitted from 3x off, the noise estimated (not given), the recordings in parallel threads.
// Target: <= 10 s on 2 cores.
// Where the time goes (one evaluation: the 6 rollouts with sensitivities, 1038-1672 adaptive
// substeps each, 2.1-3.3 per frame): ~3.2 s of CPU, about half the implicit steps (5.2 Newton
// iterations per substep, half of them chord steps) and half their sensitivities; the whip's
// rollout costs ~2x the others (the threads take it first). The objective is not smooth below
// its noise: where a trial's replayed substep fails, the rest of that recording adapts anew (the
// whip's at t ~ 3 s from the third trial on), and the cost jumps by ~1e4 (0.2 %) between points
// 1e-9 apart where one sigma of the parameters moves it by ~1e2. The search stops at the first
// trial within the parameters' 95 % confidence region that raises the cost (docs/performance.md,
// "Motion fit of six recordings"): 7 rollouts, the values those 13 rollouts ended at before.
void BM_FitSixRecordings500Frames(benchmark::State& st) {
  std::vector<MotionRecordingData> recordings;
  for (unsigned seed : {1u, 2u})
    recordings.push_back({"gentle", testing::kFrameInterval, testing::Recording(5.0, 1e-3, 0.02, seed)});
  for (testing::HardMotion m : {testing::HardMotion::kWhip, testing::HardMotion::kPull,
                                testing::HardMotion::kLoop, testing::HardMotion::kFold})
    recordings.push_back({testing::HardMotionName(m), testing::kFrameInterval,
                          testing::HardRecording(m, 5.0, 1e-3, 0.02, 7)});
  Scene start = testing::Cable();
  start.dynamics->time_step = testing::kFrameInterval;
  start.material.bend_stiffness *= 3.0;
  start.material.damping *= 3.0;
  DefaultTwistDamping(&start.material);
  MotionFitResult r;
  for (auto _ : st) {
    r = FitMotion(start, recordings, {"bend_stiffness", "damping"}, RolloutOptions(),
                  StaticsOptions(), MotionFitOptions());
    benchmark::DoNotOptimize(r.values.data());
  }
  if (r.values.size() != 2) {
    st.SkipWithError(("the fit failed: " + r.message).c_str());
    return;
  }
  st.counters["converged"] = r.converged;
  st.counters["rollouts"] = r.evaluations;
  st.counters["iterations"] = r.iterations;
  st.counters["run_seconds"] = r.run_seconds;
  st.counters["bend_stiffness_over_truth"] = r.values[0] / testing::Cable().material.bend_stiffness;
  st.counters["damping_over_truth"] = r.values[1] / testing::Cable().material.damping;
  st.counters["residual_variance"] = r.residual_variance;
  st.counters["error_mm"] = 1e3 * r.error_fitted;
}
BENCHMARK(BM_FitSixRecordings500Frames)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

// The example's swing seen by tests/data/synth/cam_swing.yaml: the truth of protocol.yaml run
// once in the setup, 10 pixels per frame (the middles of the edges' images) with Gaussian noise
// of 0.5 px; every timed iteration fits from the example's starts.
void BM_FitPixelSequences(benchmark::State& st) {
  const std::string example = std::string(RODFIT_SOURCE_DIR) + "/data/suture_swing_fit/";
  const std::string camera_file = std::string(RODFIT_SOURCE_DIR) + "/tests/data/synth/cam_swing.yaml";
  if (!std::filesystem::is_regular_file(example + "protocol.yaml") ||
      !std::filesystem::is_regular_file(camera_file)) {
    st.SkipWithError(("no example at " + example).c_str());
    return;
  }
  const Experiment truth = LoadExperiment(example + "protocol.yaml");
  const Experiment experiment = LoadExperiment(example + "experiment.yaml");
  const Camera camera = LoadCamera(camera_file);
  const std::vector<double> arc = CaseVertexArcLengths(truth.scene, 0);
  std::vector<double> t;
  for (int k = 0; k <= 25; ++k) t.push_back(0.01 * k);
  const CaseSamples run = SampleCaseDynamics(truth.scene, 0, truth.statics, arc, t, {});
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.5);
  ObservationSequence seq;
  for (size_t k = 0; k < run.x.size(); ++k) {
    std::vector<Eigen::Vector2d> pixels;
    for (size_t j = 0; j + 1 < arc.size(); ++j) {
      Eigen::Vector2d uv;
      Project(camera, Eigen::Vector3d(0.5 * (run.x[k].col(j) + run.x[k].col(j + 1))), &uv);
      pixels.push_back(uv + Eigen::Vector2d(noise(rng), noise(rng)));
    }
    seq.frames.push_back(
        {t[k],
         MakeShapeMeasurement(
             "image_points", "image_points",
             ImageCurveObservation(static_cast<int>(arc.size()), camera, pixels, 0.5)),
         {}});
  }
  const std::vector<std::string> names = FittedNames(experiment);
  const MotionFitOptions options = SequenceFitOptionsOf(experiment, names);
  MotionFitResult r;
  for (auto _ : st) {
    r = FitSequences(experiment.scene, {seq}, names, experiment.statics, options);
    benchmark::DoNotOptimize(r.values.data());
  }
  if (!r.converged) st.SkipWithError(("the fit did not converge: " + r.message).c_str());
  st.counters["iterations"] = r.iterations;
  st.counters["runs"] = r.evaluations;
}
BENCHMARK(BM_FitPixelSequences)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace rodfit

BENCHMARK_MAIN();
