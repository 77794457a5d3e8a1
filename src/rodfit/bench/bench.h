// The scenarios of `rodfit bench` (docs/cli.md, "bench"), a library beside the references
// (src/rodfit/reference/) that the command (src/cli/bench_command.cc) runs: the ladder and stress
// suite (ladder.cc), independent references (references.cc), what each skip saves (skips.cc) and
// the fit's recovery of the bundled recipes (fit_recovery.cc). Every part returns rows of the one
// bench.csv layout.
#pragma once

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"

namespace bench {

struct Row {
  std::string problem, family, setting;
  double error = 0.0;
  std::string error_unit;  // "L" (max vertex distance / length), "relative"
  double t_median = 0.0, t_min = 0.0, t_max = 0.0;  // [s]
  int iterations = 0;
  bool converged = false, stable = false;
  std::string verdict;  // stress: ok | WRONG; skips: same | DIFFERENT | not measured
  std::string note;
};

/// Runs `once` `repeats` times; the median, min and max of its wall times.
template <typename F>
void Time(int repeats, F once, Row* row) {
  std::vector<double> t;
  for (int k = 0; k < repeats; ++k) {
    const auto a = std::chrono::steady_clock::now();
    once();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count());
  }
  std::sort(t.begin(), t.end());
  row->t_median = t[t.size() / 2];
  row->t_min = t.front();
  row->t_max = t.back();
}

/// For short runs whose difference matters (the skips): `once` run untimed first (allocations,
/// caches), then repeated until `min_seconds` have passed and at least `min_repeats` times
/// (at most 10,000); the median, min and max.
template <typename F>
void TimeAtLeast(double min_seconds, int min_repeats, F once, Row* row) {
  once();
  std::vector<double> t;
  double total = 0.0;
  while ((total < min_seconds || static_cast<int>(t.size()) < min_repeats) && t.size() < 10000) {
    const auto a = std::chrono::steady_clock::now();
    once();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count());
    total += t.back();
  }
  std::sort(t.begin(), t.end());
  row->t_median = t[t.size() / 2];
  row->t_min = t.front();
  row->t_max = t.back();
}

/// Two variants of one run (a skip with and without): each run once untimed, then alternated,
/// a then b, until both have run `min_repeats` times and for `min_seconds` together (at most
/// 10,000 times each), so that a change of the machine's load falls on both alike; the median,
/// min and max of each.
template <typename A, typename B>
void TimeAlternating(double min_seconds, int min_repeats, A a, B b, Row* row_a, Row* row_b) {
  a();
  b();
  std::vector<double> ta, tb;
  double total = 0.0;
  auto timed = [](auto& f) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  while ((total < min_seconds || static_cast<int>(ta.size()) < min_repeats) && ta.size() < 10000) {
    ta.push_back(timed(a));
    tb.push_back(timed(b));
    total += ta.back() + tb.back();
  }
  for (auto [t, row] : {std::make_pair(&ta, row_a), std::make_pair(&tb, row_b)}) {
    std::sort(t->begin(), t->end());
    row->t_median = (*t)[t->size() / 2];
    row->t_min = t->front();
    row->t_max = t->back();
  }
}

/// Prints a row as it comes (a full ladder takes minutes).
void Print(const Row& r);

/// The ladder (ladder.cc): reference problems with exact answers over settings (statics: end
/// moments, circle and helix, segments and tolerances, and the references below; dynamics: a
/// cantilever's first frequency and a damped decay per integrator and time step). `quick`: a
/// shorter ladder (up to 1000 segments, one repeat, no explicit run).
std::vector<Row> Ladder(bool quick);

/// The stress suite: every row right (ok) or failed with a message; a wrong answer returned as
/// success is marked WRONG.
std::vector<Row> Stress();

/// The rows as bench.csv, as the page DIR/index.html (error against time) and as the Pareto
/// figure (empty when no problem has two settings).
std::string Csv(const std::vector<Row>& rows);
std::string Html(const std::vector<Row>& rows);
std::string ParetoSvg(const std::vector<Row>& rows);

/// Statics rows against independent references (references.cc), one solve of one
/// setting each: a heavy rod clamped at both ends and a rest-curved anisotropic rod in 3-D against
/// the Kirchhoff shooting solver (error: max vertex distance / L; family "segments"), a rod on
/// tissue springs under a point load against Hetenyi's beam on an elastic foundation (max
/// deflection error / peak; "segments") and the cross-section ring under a point load against
/// the thin-ring closed form (relative error of the diameter changes; "nodes").
Row HeavyClampedClamped(int segments, int repeats);
Row RestCurved3D(int segments, int repeats);
Row WinklerPointLoad(int segments, int repeats);
Row RingPointLoad(int nodes, int repeats);

/// `--skips`: each skip timed with and without on the same problem, two rows per comparison
/// (family "with skip" / "without skip"), error = the largest difference between the two
/// answers, the saving in the "with" row's note; a table of them on stdout.
std::vector<Row> Skips(bool quick, const std::string& calibration_dir);

/// A recipe's fit input from synthetic data: `protocol` (its parameter values the truth)
/// synthesized as `rodfit synth` does into `dir` (seed 7), with Gaussian noise of `noise` times
/// its sigmas (none at 0), read back with the parameter values of `start` (the recipe's
/// experiment.yaml) to start the fit from.
rodfit::FitInput SynthesizedFitInput(const rodfit::Experiment& protocol,
                                     const rodfit::Experiment& start, double noise,
                                     const std::string& dir);

/// Fit recovery of the bundled recipes (calibration_dir/<recipe>/protocol.yaml, its parameter
/// values the truth, synthesized at noise 0, 1x and 3x its sigmas, fitted from the start
/// values of calibration_dir/<recipe>/experiment.yaml): one row per fitted parameter and noise
/// level, error = |fitted / truth - 1|. No rows (and a line on stdout) when the directory
/// is missing.
std::vector<Row> FitRecovery(bool quick, const std::string& calibration_dir);

}  // namespace bench
