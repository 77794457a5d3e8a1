// What synth's generators share, one observation entry at a time (synth.h's measurement model):
// the seeded random stream, the entry's context (the solved case, its camera, where messages
// point), noise, outliers and drops, and every observation kind's generator. The observation
// kinds (rodfit/pipeline/observation_kind.h) register these; the pipeline's synth driver
// (rodfit/pipeline/synthesize.h) runs them entry by entry. Internal to synth and the pipeline.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/shapes_csv.h"
#include "rodfit/observe/camera.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/synth/synth.h"

namespace rodfit {

/// Random numbers that are the same on every standard library: only raw std::mt19937 output
/// (whose sequence the standard fixes) is used; the <random> distributions are
/// implementation-defined.
class Random {
 public:
  /// The stream of `seed` and `key` (an entry's output path: FNV-1a of it), so that an entry's
  /// data depends on what it is, not where it is.
  Random(std::uint32_t seed, const std::string& key);
  std::mt19937& engine() { return engine_; }
  /// [0, 1) with 53 random bits.
  double Uniform();
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  /// Standard normal by Marsaglia's polar method (no trigonometry), the pair's second kept.
  double Normal();
  /// Uniform integer in [0, n) by rejection, free of modulo bias. n >= 1.
  std::uint32_t Index(std::uint32_t n);

 private:
  std::mt19937 engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

/// Everything one observation entry needs to be synthesized.
struct SynthEntry {
  const Experiment* experiment;
  const SynthOptions* options;
  const CaseShape* shape;
  const CaseSolution* solution;  ///< the case solved (model, state, poke)
  const ObservationSpec* spec;
  const Camera* camera;          ///< image kinds only
  std::string key;               ///< cases[c].observations[o]
  std::string camera_label;      ///< the camera file as written in messages
  Random* random;
  int case_index;                ///< the entry's case in experiment->scene.cases
  std::string when;              ///< a sequence's frame: " at t = ... s"; empty otherwise
  std::string file;              ///< the output path, relative to the output directory
  /// A moving case's whole-rod vertex arc lengths (CaseVertexArcLengths), where its shape at
  /// each time is taken; empty for a static case.
  std::vector<double> vertex_arc_length;

  [[noreturn]] void Fail(const std::string& message) const {
    throw InputError(experiment->path, spec->line, key, message);
  }
  std::string CaseName() const { return "'" + shape->name + "'" + when; }
};

/// Indices of round(fraction * n) distinct samples, increasing (partial Fisher–Yates).
std::vector<int> ChooseOutliers(double fraction, int n, Random* random);

/// Arc lengths of markers: the entry's list, or `count` evenly spaced with the last at the tip
/// (a marker on the clamp carries no information); default one per free vertex.
std::vector<double> MarkerArcLengths(const ObservationSpec& spec, const RodSpec& rod);

/// Gaussian noise of sigma on every coordinate, drawn sample by sample (none without
/// options->add_noise).
template <int N>
void AddNoise(const SynthEntry& entry, double sigma, std::vector<Eigen::Matrix<double, N, 1>>* p) {
  if (!entry.options->add_noise) return;
  for (auto& q : *p) {
    for (int d = 0; d < N; ++d) q(d) += sigma * entry.random->Normal();
  }
}
/// With the entry's sigma.
template <int N>
void AddNoise(const SynthEntry& entry, std::vector<Eigen::Matrix<double, N, 1>>* p) {
  AddNoise(entry, entry.spec->sigma, p);
}

/// Replaces the entry's fraction of outliers by uniform points in the box [lo, hi]; returns how
/// many. Drawn after the noise: first the choice, then the points.
template <int N>
int ReplaceOutliers(const SynthEntry& entry, const Eigen::Matrix<double, N, 1>& lo,
                    const Eigen::Matrix<double, N, 1>& hi,
                    std::vector<Eigen::Matrix<double, N, 1>>* p) {
  if (!entry.options->add_noise) return 0;
  const std::vector<int> chosen =
      ChooseOutliers(entry.spec->outliers, static_cast<int>(p->size()), entry.random);
  for (const int i : chosen) {
    for (int d = 0; d < N; ++d) (*p)[i](d) = entry.random->Uniform(lo(d), hi(d));
  }
  return static_cast<int>(chosen.size());
}

/// "case NAME: FILE: TYPE, n samples[, k outliers][, d outside the image dropped]".
std::string Summary(const SynthEntry& entry, int n, int outliers, int dropped);

/// The bounding box of the solved vertices grown by options.outlier_box_margin * L.
void OutlierBox(const SynthEntry& entry, Eigen::Vector3d* lo, Eigen::Vector3d* hi);

/// Solves every case in order (a case may start from the previous one's solution); a case that
/// is not a valid rod or does not converge is an InputError at its entry.
std::vector<CaseSolution> SolveCases(const Experiment& experiment, const StaticsOptions& statics);

// The generators, one per kind (and per moving kind's sequence): the file's contents, and in
// *report a line of what was written (synth.h describes each).
std::string SynthMarkers3d(const SynthEntry& entry, std::string* report);
std::string SynthMarkers3dSequence(const SynthEntry& entry, std::string* report);
std::string SynthPoints3d(const SynthEntry& entry, std::string* report);
std::string SynthPoints3dSequence(const SynthEntry& entry, std::string* report);
std::string SynthImagePoints(const SynthEntry& entry, std::string* report);
std::string SynthImagePointsSequence(const SynthEntry& entry, std::string* report);
std::string SynthImage(const SynthEntry& entry, std::string* report);
std::string SynthGraspForce(const SynthEntry& entry, std::string* report);
std::string SynthReaction(const SynthEntry& entry, std::string* report);
std::string SynthReactionSequence(const SynthEntry& entry, std::string* report);
std::string SynthSurfacePoints(const SynthEntry& entry, std::string* report);

}  // namespace rodfit
