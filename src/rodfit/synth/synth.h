// `rodfit synth`'s layer: synthetic observations of an experiment whose parameter values are taken
// as the truth (docs/cli.md, "synth"); the driver that runs every entry's generator is the
// pipeline's (rodfit/pipeline/synthesize.h), the generators are in synth_entry.h. Every case is
// solved to equilibrium; every observation entry of every case gets the file it names: `markers3d`
// (s,x,y,z at the entry's `s` or `count` arc lengths), `points3d` (x,y,z centre-line samples),
// `image_points` (s,u,v at given arc lengths, or u,v evenly spaced along the projected centre-line)
// and `images` (a PNG of the tube of the rod's radius as the camera sees it, RenderThreadImage) and
// `grasp_force` (a haptic log of an instrument dragging the grasped point in steps, see
// SynthOptions). Gaussian noise of the entry's `sigma` [m, px or N] and a fraction `outliers` of
// uniformly random points complete the measurement model. Beside them go DIR/experiment.yaml (the
// experiment re-emitted with every path relative to DIR, camera files copied in, so DIR is
// self-contained) and DIR/truth.json (the parameters and the solved vertices). Randomness is
// std::mt19937 seeded per entry from the run's seed and the entry's output path, so an entry's data
// does not depend on the order of entries; normal deviates use Marsaglia's polar method on raw
// 32-bit draws, so a seed gives the same bytes on every standard library.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "rodfit/io/experiment.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/shapes_csv.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

/// The files synth writes beside the observations: the re-emitted experiment and the truth.
inline constexpr char kSynthExperimentFile[] = "experiment.yaml";
inline constexpr char kSynthTruthFile[] = "truth.json";

struct SynthOptions {
  std::uint32_t seed = 1;    ///< run seed; every entry derives its own from it
  StaticsOptions statics;    ///< solver settings for the true shapes
  /// Outliers of 3-D types are drawn uniformly in the solved vertices' bounding box grown by
  /// this fraction of the rod length on every side (image types: the whole image).
  double outlier_box_margin = 0.1;
  /// false: no Gaussian noise, no outliers, no pixel noise (exact samples; images keep `blur`).
  bool add_noise = true;

  /// `grasp_force` haptic logs. The instrument holds the entry's grasped point s and drags it
  /// from its rest position P_0 = clamp position + s * unit clamp tangent (the straight rest
  /// rod) to the case's grasp.position P_N in N = the entry's `count` (default 8) equal steps
  /// P_k = P_0 + k/N (P_N - P_0). The log starts at t = 0 with the tool at P_0 and moves at once;
  /// each step is a move to P_k at haptic_move_speed_factor * max_speed (at least two sample
  /// intervals, so a step shorter than 2 * that speed / rate moves more slowly), then a dwell of
  /// haptic_dwell_time with the tool still at P_k, the move's arrival sample being the dwell's
  /// first. Forces: at P_0 and during dwells the solved GraspReaction at P_k (each P_k solved
  /// from the straight state, as `simulate` and `fit` do); during moves linear between the two
  /// neighbouring P_k; Gaussian noise of the entry's sigma on every force component. Tool
  /// positions get Gaussian noise of haptic_tool_noise_factor * max_speed / rate per coordinate
  /// (0.5 um at the defaults), so that the speed the fit estimates for a still tool (central
  /// differences) is about 0.1 max_speed: realistic, yet above max_speed with probability below
  /// 1e-10 per sample (that for the log's last sample, whose difference is one-sided; far less
  /// elsewhere), while the moves stay well above it. The first and last sample of a dwell border
  /// a move, which the central difference sees (about half the move speed): the fit drops them
  /// with the moves, so each dwell of D = haptic_dwell_time * rate samples gives D - 2
  /// quasi-static samples (the final dwell D - 1). Rows: 1 + N (M - 1 + D), M the intervals of
  /// a move; more than 1e6 is an error.
  double haptic_rate = 200.0;              ///< [Hz] log sample rate
  double haptic_dwell_time = 0.5;          ///< [s] tool still at each step, >= 3 samples
  double haptic_move_speed_factor = 20.0;  ///< move speed / max_speed, > 2
  double haptic_tool_noise_factor = 0.1;   ///< tool noise sigma / (max_speed / rate), in [0, 0.2]
  int haptic_default_steps = 8;            ///< steps when the entry gives no `count`, >= 1

  bool Check(std::string* why) const;
};

/// Every file synth writes, in memory: paths relative to the output directory, contents as bytes.
/// Order: observation files (cases and entries in file order), camera copies, experiment.yaml,
/// truth.json.
struct SynthBundle {
  std::vector<std::pair<std::string, std::string>> files;
  std::vector<CaseShape> truth;  ///< the solved shape of every case, in case order
  /// Human-readable lines, one per observation entry: file, sample count, dropped, outliers.
  std::vector<std::string> report;
};

/// Writes a bundle into `output_dir` (created if missing), all files at once (StagedDirectory):
/// a failure leaves `output_dir` as it was. Throws InputError if `output_dir`/experiment.yaml is
/// the input experiment itself (`experiment_path`), or any file would overwrite one of `inputs`
/// (a camera copied onto itself when DIR is the experiment's folder), before anything is written.
void WriteSynthBundle(const SynthBundle& bundle, const std::string& output_dir,
                      const std::string& experiment_path = "",
                      const std::vector<InputFile>& inputs = {});

/// Where synth puts an input path inside the output directory: its path relative to the
/// experiment's folder when that stays inside it, else its file name alone.
std::string SynthRelativePath(const std::string& path, const std::string& experiment_directory);

/// The experiment file's text re-emitted (yaml-cpp) with every observation's `file` and `camera`
/// replaced by map_path(resolved path), other keys and their values' text as written (comments
/// are lost). `experiment` must be ParseExperiment(yaml_text, ...) so that entries correspond.
/// Throws InputError when the text no longer parses.
std::string EmitExperimentYaml(const std::string& yaml_text, const Experiment& experiment,
                               const std::function<std::string(const std::string&)>& map_path);

/// The truth.json text: {"format": "rodfit-truth", "version": 1, "seed": N, "parameters":
/// {name: value} (a moving scene's with its rod's linear_density), "cases": [{"name": ...,
/// "vertices": [[x, y, z], ...]}]}.
std::string FormatTruthJson(const Experiment& experiment, const std::vector<CaseShape>& truth,
                            std::uint32_t seed);

/// Observation CSV text with the columns of docs/formats.md, numbers at round-trip precision.
std::string FormatMarkersCsv(const std::vector<double>& s, const std::vector<Eigen::Vector3d>& p);
std::string FormatPoints3dCsv(const std::vector<Eigen::Vector3d>& p);
/// One row of a haptic log: time, instrument position, force the tissue exerts on it.
struct HapticLogRow {
  double t = 0.0;                                    ///< [s]
  Eigen::Vector3d tool = Eigen::Vector3d::Zero();    ///< [m]
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   ///< [N]
};
/// `t,tool_x,tool_y,tool_z,fx,fy,fz`, the columns `grasp_force` reads.
std::string FormatHapticLogCsv(const std::vector<HapticLogRow>& rows);
/// `s,u,v` when s is given (same size as uv), else `u,v`.
std::string FormatImagePointsCsv(const std::vector<Eigen::Vector2d>& uv,
                                 const std::vector<double>* s = nullptr);

/// Position at rest arc length s [m] on a solved shape: linear between the vertices around s
/// (the material point at s). s is clamped to [0, L].
Eigen::Vector3d PointAtArcLength(const CaseShape& shape, double s);

}  // namespace rodfit
