// `rodfit bench --skips` (docs/cli.md, "bench"): what each skip of work a scene does not need
// saves, measured by running the same problem with and without it. Each comparison gives two
// rows of bench.csv (family "with skip" and "without skip"): error = the largest difference
// between the two answers (vertex positions / L, or fitted parameters, relative), which must be
// below 1e-10 (verdict "same", else "DIFFERENT"), and the saving in % in the "with" row's note.
// A skip that cannot be measured honestly gets one row saying why (verdict "not measured").
#include <stdlib.h>  // mkdtemp

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include "rodfit/bench/bench.h"
#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/dynamics.h"
#include "rodfit/solve/statics.h"
#include "rodfit/pipeline/experiment.h"

namespace bench {
namespace {

using rodfit::Vec3;

/// Two answers are "the same" below this: positions in L, parameters relative.
constexpr double kSameAnswer = 1e-10;

struct Comparison {
  std::string skip, setting;
  Row with, without;
};

/// Fills the two rows of a comparison from their timings and the two answers' difference.
Comparison Compare(const std::string& skip, const std::string& setting, const std::string& unit,
                   Row with, Row without, double difference, const std::string& what,
                   const std::string& what_without) {
  Comparison c{skip, setting, with, without};
  for (Row* r : {&c.with, &c.without}) {
    r->problem = "skip/" + skip;
    r->setting = setting;
    r->error = difference;
    r->error_unit = unit;
    r->verdict = difference <= kSameAnswer ? "same" : "DIFFERENT";
  }
  c.with.family = "with skip";
  c.without.family = "without skip";
  const double saving = 100.0 * (1.0 - c.with.t_median / c.without.t_median);
  char text[160];
  std::snprintf(text, sizeof(text), "saving %.1f %% (%s)", saving, what.c_str());
  c.with.note = text;
  c.without.note = what_without;
  return c;
}

// --- twist elimination: the statics of rods nothing can twist ---

/// A heavy isotropic cantilever (L = 1 m, B = 1 N m^2, GJ = B / 1.3, EA = 1e6 N, weight 3 B / L^2
/// along -z), clamped along x with d1 = z; `tilted`: the clamp 0.4 rad above horizontal and a
/// sideways tip force (0.5, 2, -1.5) N, a 3-D shape.
rodfit::Scene HeavyCantilever(int segments, bool tilted) {
  rodfit::Scene s;
  s.rod.length = 1.0;
  s.rod.segments = segments;
  s.rod.radius = 0.01;
  s.rod.linear_density = 3.0 / 9.81;
  s.material.bend_stiffness = 1.0;
  s.material.twist_stiffness = 1.0 / 1.3;
  s.material.stretch_stiffness = 1e6;
  s.gravity = Vec3(0, 0, -9.81);
  rodfit::LoadCase c;
  c.name = tilted ? "tilted" : "planar";
  c.clamp.tangent = tilted ? Vec3(std::cos(0.4), 0, std::sin(0.4)) : Vec3::UnitX();
  c.clamp.normal = Vec3::UnitZ();
  if (tilted) c.tip_force = Vec3(0.5, 2.0, -1.5);
  s.cases.push_back(c);
  return s;
}

double MaxDistance(const rodfit::Mat3X& a, const rodfit::Mat3X& b, double L) {
  if (a.cols() != b.cols()) return NAN;
  return (a - b).colwise().norm().maxCoeff() / L;
}

/// One statics solve of case 0 from the straight rod (`extra` run after it).
struct SolveRun {
  const rodfit::Scene& scene;
  rodfit::StaticsOptions options;
  std::function<void(const rodfit::CaseSolution&)> extra;
  rodfit::CaseSolution solution;
  void operator()() {
    solution = rodfit::SolveCase(scene, 0, nullptr, options);
    if (extra) extra(solution);
  }
  void Fill(Row* row) const {
    row->converged = solution.summary.converged;
    row->stable = solution.summary.stable;
    row->iterations = solution.summary.iterations;
    if (!row->converged) row->note = solution.summary.reason;
  }
};

/// The two solves timed alternately; their rows.
void TimeSolves(double seconds, SolveRun* a, SolveRun* b, Row* with, Row* without) {
  TimeAlternating(seconds, 5, [&] { (*a)(); }, [&] { (*b)(); }, with, without);
  a->Fill(with);
  b->Fill(without);
}

Comparison TwistElimination(const std::string& name, const rodfit::Scene& scene, double seconds) {
  rodfit::StaticsOptions off;
  off.eliminate_twist = false;
  SolveRun run_a{scene, {}, {}, {}}, run_b{scene, off, {}, {}};
  Row with, without;
  TimeSolves(seconds, &run_a, &run_b, &with, &without);
  const rodfit::CaseSolution &a = run_a.solution, &b = run_b.solution;
  const std::string what = a.summary.twist_eliminated ? "twist angles dropped from Newton's unknowns"
                                                      : "NOT eliminated (the scene can twist)";
  const std::string what_without = b.summary.twist_eliminated
                                       ? "NOT kept (eliminate_twist ignored)"
                                       : "twist angles kept (StaticsOptions::eliminate_twist off)";
  return Compare("twist_elimination", name + " n=" + std::to_string(scene.rod.segments), "L", with,
                 without, MaxDistance(a.shape, b.shape, scene.rod.length), what, what_without);
}

// --- the cross-section ring without a poke, the mass matrix for a static case ---

/// A bowel segment on springs (data/scenes/bowel_poke.yaml) with the cross-section model.
rodfit::Scene Bowel(int segments) {
  rodfit::Scene s;
  s.rod.length = 0.15;
  s.rod.segments = segments;
  s.rod.radius = 0.012;
  s.rod.linear_density = 0.45;
  s.material.bend_stiffness = 2.0e-4;
  s.material.twist_stiffness = 1.5e-4;
  s.material.stretch_stiffness = 40;
  s.material.spring_stiffness = 300;
  s.material.ring_bend_stiffness = 2.0e-5;
  s.material.ring_stretch_stiffness = 5.0;
  s.springs.push_back(rodfit::SpringZone{0.0, 0.15, ""});
  rodfit::SectionSpec section;
  section.radius = 0.012;
  section.nodes = 32;
  section.stop_factor = 0.002;
  s.section = section;
  rodfit::LoadCase c;
  c.name = "sag";
  c.tip_force = Vec3(0, -0.02, 0);
  s.cases.push_back(c);
  return s;
}

Comparison SectionWithoutPoke(int segments, double seconds) {
  // Without the skip a solver would solve the ring of every case: here the same case with a
  // poke of zero force at mid-length, which leaves the rod as it is and solves the ring.
  const rodfit::Scene plain = Bowel(segments);
  rodfit::Scene poked = plain;
  poked.cases[0].poke = rodfit::Poke{0.075, Vec3::Zero()};
  SolveRun run_a{plain, {}, {}, {}}, run_b{poked, {}, {}, {}};
  Row with, without;
  TimeSolves(seconds, &run_a, &run_b, &with, &without);
  const rodfit::CaseSolution &a = run_a.solution, &b = run_b.solution;
  std::string what = "ring of " + std::to_string(plain.section->nodes) + " nodes solved";
  if (a.poke || !b.poke) what = "unexpected: " + what + " " + (a.poke ? "with" : "without");
  return Compare("section_without_poke", "bowel n=" + std::to_string(segments), "L", with, without,
                 MaxDistance(a.shape, b.shape, plain.rod.length), "no poke: no ring solved",
                 what + " for a poke of zero force");
}

Comparison MassForStatics(int segments, double seconds) {
  // Without the skip a static case would also set up the dynamics: the stepper's lumped mass,
  // drag and damping band.
  const rodfit::Scene scene = HeavyCantilever(segments, false);
  SolveRun run_a{scene, {}, {}, {}};
  SolveRun run_b{scene, {}, [](const rodfit::CaseSolution& solved) {
    const rodfit::DynamicsStepper stepper(*solved.model, rodfit::DynamicsOptions());
    (void)stepper;
  }, {}};
  Row with, without;
  TimeSolves(seconds, &run_a, &run_b, &with, &without);
  const rodfit::CaseSolution &a = run_a.solution, &b = run_b.solution;
  return Compare("mass_for_statics", "heavy cantilever n=" + std::to_string(segments), "L", with,
                 without, MaxDistance(a.shape, b.shape, scene.rod.length),
                 "no dynamics set up for a static case",
                 "lumped (diagonal) mass, drag and damping band of the dynamics built too");
}

// --- the fit: Jacobian columns of fixed parameters, twist elimination in a fit ---

/// The recipe's protocol synthesized without noise into a temporary folder and read back with
/// the recipe's start values (SynthesizedFitInput). False (and *why) when the recipe is missing.
bool RecipeFitInput(const std::string& recipe_dir, rodfit::FitInput* input, std::string* why) {
  namespace fs = std::filesystem;
  if (!fs::exists(recipe_dir + "/protocol.yaml") || !fs::exists(recipe_dir + "/experiment.yaml")) {
    *why = recipe_dir + ": no protocol.yaml and experiment.yaml";
    return false;
  }
  std::string dir = (fs::temp_directory_path() / "rodfit-bench-XXXXXX").string();
  if (!::mkdtemp(dir.data())) {
    *why = "cannot create a temporary folder";
    return false;
  }
  *input = SynthesizedFitInput(rodfit::LoadExperiment(recipe_dir + "/protocol.yaml"),
                               rodfit::LoadExperiment(recipe_dir + "/experiment.yaml"), 0.0,
                               dir + "/data");
  std::error_code ec;
  fs::remove_all(dir, ec);
  return true;
}

double MaxRelativeDifference(const rodfit::FitResult& a, const rodfit::FitResult& b) {
  if (a.parameters.size() != b.parameters.size()) return NAN;
  double worst = 0.0;
  for (size_t k = 0; k < a.parameters.size(); ++k)
    worst = std::max(worst, std::abs(a.parameters[k].value / b.parameters[k].value - 1.0));
  return worst;
}

/// Two fits timed alternately; their rows.
void TimeFits(double seconds, const rodfit::FitInput& input_a, const rodfit::FitOptions& options_a,
              const rodfit::FitInput& input_b, const rodfit::FitOptions& options_b,
              rodfit::FitResult* a, rodfit::FitResult* b, Row* row_a, Row* row_b) {
  TimeAlternating(seconds, 3, [&] { *a = rodfit::Fit(input_a, options_a); },
                  [&] { *b = rodfit::Fit(input_b, options_b); }, row_a, row_b);
  for (auto [result, row] : {std::make_pair(a, row_a), std::make_pair(b, row_b)}) {
    row->converged = result->success;
    row->stable = result->success;
    row->iterations = result->iterations;
    if (!result->success) row->note = result->message;
  }
}

void FitSkips(const std::string& calibration_dir, double seconds, std::vector<Comparison>* out) {
  rodfit::FitInput suture, drag;
  std::string why;
  rodfit::FitOptions o;
  o.num_threads = 1;  // timings without the threads' scheduling noise
  if (RecipeFitInput(calibration_dir + "/suture_cantilever", &suture, &why)) {
    rodfit::FitOptions all = o;
    all.jacobian_of_fixed_parameters = true;
    rodfit::FitResult a, b;
    Row with, without;
    TimeFits(seconds, suture, o, suture, all, &a, &b, &with, &without);
    out->push_back(Compare("jacobian_fixed_parameters", "suture_cantilever fit", "relative", with,
                           without, MaxRelativeDifference(a, b),
                           "Jacobian columns of B1 and B2 only",
                           "columns of the held GJ and EA computed too, then dropped"));
  } else {
    std::cout << "skip/jacobian_fixed_parameters: not measured (" << why << ")\n";
  }
  if (RecipeFitInput(calibration_dir + "/tissue_drag", &drag, &why)) {
    rodfit::FitInput full = drag;
    full.statics.eliminate_twist = false;
    rodfit::FitResult a, b;
    Row with, without;
    TimeFits(seconds, drag, o, full, o, &a, &b, &with, &without);
    out->push_back(Compare("twist_elimination", "tissue_drag fit", "relative", with, without,
                           MaxRelativeDifference(a, b),
                           "isotropic bowel on springs and a grasp: every solve position-only",
                           "twist angles kept (StaticsOptions::eliminate_twist off)"));
  } else {
    std::cout << "skip/twist_elimination (fit): not measured (" << why << ")\n";
  }
}

}  // namespace

std::vector<Row> Skips(bool quick, const std::string& calibration_dir) {
  // The two variants run alternately for at least this long [s] together (and 5 times each):
  // sub-millisecond solves need many repeats for a median whose differences are the skip's and
  // not the machine's.
  const double seconds = quick ? 0.1 : 0.5;
  std::vector<Comparison> comparisons;
  std::vector<int> segments = {10, 30, 100, 300, 1000};
  if (!quick) segments.push_back(3000);
  for (int n : segments)
    comparisons.push_back(TwistElimination("planar heavy cantilever", HeavyCantilever(n, false), seconds));
  comparisons.push_back(TwistElimination("3-D tip force", HeavyCantilever(100, true), seconds));
  comparisons.push_back(SectionWithoutPoke(60, seconds));
  comparisons.push_back(MassForStatics(100, seconds));
  FitSkips(calibration_dir, seconds, &comparisons);

  std::vector<Row> rows;
  for (const Comparison& c : comparisons) {
    rows.push_back(c.with);
    rows.push_back(c.without);
  }
  Row vision;
  vision.problem = "skip/vision_for_markers";
  vision.family = "with skip";
  vision.setting = "marker-only fit";
  vision.error = NAN;
  vision.error_unit = "-";
  vision.verdict = "not measured";
  vision.note =
      "a marker-only experiment has no images: the vision (image loading, centre-line "
      "extraction) is reached only from `images` observations, so there is nothing to run "
      "without the skip";
  rows.push_back(vision);

  std::printf("\n%-27s %-32s %11s %11s %8s %10s  %s\n", "skip", "problem", "with [s]",
              "without [s]", "saving", "max diff", "answer");
  for (const Comparison& c : comparisons) {
    std::printf("%-27s %-32s %11.4g %11.4g %7.1f%% %10.2g  %s\n", c.skip.c_str(),
                c.setting.c_str(), c.with.t_median, c.without.t_median,
                100.0 * (1.0 - c.with.t_median / c.without.t_median), c.with.error,
                c.with.verdict.c_str());
  }
  std::printf("%-27s %-32s %s\n", "vision_for_markers", vision.setting.c_str(),
              "not measured: no images to run the vision on");
  std::fflush(stdout);
  return rows;
}

}  // namespace bench
