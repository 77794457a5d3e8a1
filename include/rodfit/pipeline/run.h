// The library's entry points (docs/library.md, "Entry points"): what each command of the CLI does,
// as one call that returns its results with their warnings. Nothing here prints, exits or writes
// a file unless its options name an output; the CLI parses its options, calls one of these,
// prints and maps the result to its exit status (docs/cli.md). Pipeline layer.
//
//   FitExperiment   `rodfit fit`       the profile (JSON) of a static or moving experiment
//   SimulateScene   `rodfit simulate`  static shapes and forces, or a moving scene's trajectories
//   Rollout         `rodfit rollout`   open-loop predictions of recordings, with or without --fit
//   Synthesize      `rodfit synth`     rodfit/pipeline/synthesize.h
#pragma once

#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "rodfit/fit/fit.h"
#include "rodfit/fit/motion_fit.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/recording.h"
#include "rodfit/io/shapes_csv.h"
#include "rodfit/solve/rollout.h"

namespace rodfit {

class StagedDirectory;

/// What a long run is doing, for a progress line: a sentence and the fraction done (NaN when the
/// work's size is unknown). Called from the calling thread.
using ProgressCallback = std::function<void(const std::string& text, double fraction_done)>;

// --- fit

/// Stages a fit's report in a directory (the report layer's WriteFitReport: the pipeline does not
/// draw reports) and returns the report's own warnings.
using FitReportWriter = std::function<std::vector<std::string>(
    StagedDirectory* out, const Experiment& experiment, const FitInput& input,
    const FitResult& result, const std::vector<std::string>& warnings)>;

struct FitRunOptions {
  int num_threads = 2;  ///< cases evaluated in parallel (static fit)
  /// Where to write the profile JSON (empty: nowhere; FitRun::profile holds it). With
  /// `report_dir`, the report and the profile are committed together, or neither.
  std::string profile_path;
  std::string report_dir;         ///< the report's directory (needs write_report and profile_path)
  FitReportWriter write_report;   ///< how to draw it
  ProgressCallback progress;      ///< the fit's iterations (none: silent)
};

/// A fit's outcome. `ok` false: the run failed (`error` says why; nothing written); else the
/// result, the profile and the warnings.
struct FitRun {
  bool ok = false;
  std::string error;   ///< one line, without the experiment's path
  bool moving = false; ///< a motion fit (the experiment has a dynamics: block)
  FitResult result;
  FitOptions options;  ///< as the fit ran them (the residual check's sigmas)
  int runs = 0;        ///< moving: the rollouts the fit took
  nlohmann::json profile;  ///< the profile document (docs/formats.md, "Profile JSON")
  /// Held points the rod reaches only by stretching more than 1 %: "case NAME: SPAN".
  std::vector<std::string> stretched;
  /// The residual variance outside its chi-square band, with what it means (empty: inside).
  std::string residual_warning;
  /// The observation entries' own warnings ("case NAME: LABEL: ...", e.g. a critical twist the
  /// model does not reach within its range).
  std::vector<std::string> entry_warnings;
  /// Every warning in the order the report lists them (stretched spans with what to check, the
  /// residual warning, the entries' warnings); then the report's own (drawn without 3-D views...).
  std::vector<std::string> warnings;
  std::vector<std::string> report_warnings;
  /// Some fitted parameter is not determined by the data (its value null in the profile).
  bool all_determined = true;
  /// The residuals are far beyond the stated noise (ResidualCheck::gross): the model does not
  /// explain the data, and the values are not to be used as they stand.
  bool misfit = false;
};

/// Fits the experiment's `fit: true` parameters to its observations (the static fit, or the
/// motion fit for a moving experiment) and builds the profile; writes it (and the report) when
/// options name where. Throws InputError for bad observation files or cameras (naming file, line
/// and key); a request the fit cannot run and a fit that fails come back as ok = false.
FitRun FitExperiment(const Experiment& experiment, const FitRunOptions& options = {});

// --- simulate

struct SimulateOptions {
  /// Write the cases that solved even when one fails (else nothing is written then).
  bool keep_going = false;
  /// Where to write shapes.csv ... (static) or trajectory.csv ... (moving); empty: nowhere.
  std::string output_dir;
  /// Moving scenes: a synthetic motion-capture recording (markers.csv) of this many markers
  /// evenly spaced in s at every written frame (0: none).
  int marker_count = 0;
  double marker_noise = 0.0;  ///< [m] Gaussian, per coordinate
  double marker_drop = 0.0;   ///< fraction of samples left out (never in frames 0 and 1)
  unsigned seed = 1;          ///< of the marker noise and drops
  /// Moving scenes: run even when the estimated work or output is above the limits
  /// (EstimateMotionRun, kMaxMotionVertexSteps, kMaxMotionOutputBytes; else InputError).
  bool large = false;
  ProgressCallback progress;
};

struct SimulateRun {
  bool moving = false;  ///< a dynamics: block: trajectories instead of shapes
  /// Static: per case that solved, its centre-line, held points' forces, summary; a poked case's
  /// section ring and tube mesh (OBJ text, per case name).
  std::vector<CaseShape> shapes;
  std::vector<CaseForce> forces;
  std::vector<CaseSection> sections;
  std::vector<CaseSummaryRow> summary;
  std::vector<std::pair<std::string, std::string>> meshes;
  /// Moving: every case's written frames (with --keep-going, a failed case's frames up to there).
  std::vector<CaseMotion> motions;
  std::vector<MotionSummaryRow> motion_summary;
  /// The output files, name and text, as written to output_dir.
  std::vector<std::pair<std::string, std::string>> files;
  /// "FILE:LINE: case NAME: reason" of the first case that failed (empty: none); with
  /// keep_going false nothing was written then.
  std::string first_failure;
  /// Unstable equilibria and strains beyond a rod model's range, one line each ("FILE:LINE: case
  /// NAME: ...").
  std::vector<std::string> warnings;
  double seconds = 0.0;  ///< solve or integration time, all cases
  int steps = 0;         ///< moving: time steps, all cases
};

/// Solves every case of the scene to static equilibrium, or integrates a moving scene's cases in
/// time. Throws InputError naming the case's entry for a case that is not a valid rod, an output
/// over an input (CheckOutputFile) or a moving run above the size limits (unless `large`), and
/// std::invalid_argument for markers asked of a static scene.
SimulateRun SimulateScene(const Experiment& experiment, const SimulateOptions& options = {});

// --- rollout

/// The rollout report's writer (the report layer's WriteRolloutReport, through its input).
struct RolloutRun;
using RolloutReportWriter =
    std::function<std::vector<std::string>(StagedDirectory* out, const RolloutRun& run)>;

struct RolloutRunOptions {
  RolloutOptions rollout;
  /// Parameters to fit to the recordings first (names of the motion rows; empty: no fit), and how.
  std::vector<std::string> fit;
  MotionFitOptions fit_options;
  /// Values of a motion_fit.json replacing the scene's (with `fit`: the start): name, value and
  /// the file they came from (for messages and the inputs an output may not overwrite).
  std::vector<std::pair<std::string, double>> parameters;
  std::string parameters_path;
  /// Where to write rollout.csv (and motion_fit.json and profile.json with `fit`); empty: nowhere.
  std::string output_dir;
  std::string report_dir;             ///< the report's directory (needs write_report, output_dir)
  RolloutReportWriter write_report;
  ProgressCallback progress;
  /// Informational lines as they arise (values taken from --parameters, a defaulted twist
  /// damping, the fit's summary, halved steps); null: dropped.
  std::function<void(const std::string& line)> note;
};

struct RolloutRun {
  bool ok = false;
  std::string error;  ///< one line; nothing written
  std::string scene_path;
  std::vector<MarkerRecording> recordings;
  std::vector<RolloutResult> results;  ///< per recording
  std::shared_ptr<MotionFitResult> fit;  ///< with `fit`: the fit (else null)
  /// With `fit`: motion_fit.json (docs/cli.md, "rollout"), its text as written and its document.
  std::string fit_text;
  nlohmann::json fit_json;
  /// With `fit`: profile.json, the rod as fitted (its values and rest shape) as `rodfit fit`
  /// writes a profile (docs/formats.md, "Profile JSON"); empty when a fitted rest-shape knot is
  /// not identifiable (a warning says which).
  std::string profile_text;
  std::string csv;  ///< rollout.csv
  /// [m] mean absolute coordinate error over the recordings: all markers, predicted ones.
  double error_all = 0.0, error_predicted = 0.0;
  int samples = 0;
  /// The residual variance beyond the markers' noise (empty: within it, or no marker_sigma).
  std::string residual_warning;
  /// Every warning of the run (a fit that did not converge, residuals beyond the marker noise,
  /// halved steps), then the report's own.
  std::vector<std::string> warnings;
  std::vector<std::string> report_warnings;
  /// The residual variance beyond the markers' noise (stated, or estimated from the
  /// recordings): the misfit verdict.
  bool misfit = false;
  /// The fit did not converge (its best point kept and written) or a value is not determined.
  bool fit_not_converged = false, fit_undetermined = false;
  /// Per recording whose rollout failed: "FILE: reason" (the others ran and are written; when
  /// none ran, ok is false, error names the first failure and nothing is written).
  std::vector<std::string> failures;
  /// recordings.csv (one row per recording) and rollout_error.csv (the error per frame).
  std::string table, over_time;
};

/// The recordings of a rollout (io/recording.h), in metres or millimetres, each checked against
/// the rod's length (a unit mistake). Throws InputError for a scene without a dynamics: block and
/// for a recording that cannot be read (naming file, line and column).
std::vector<MarkerRecording> ReadRecordings(const Experiment& experiment,
                                            const std::vector<std::string>& paths,
                                            double frame_rate, bool millimetres);

/// Predicts each recording open-loop from its first frames (solve/rollout.h), after fitting
/// `options.fit` to them when asked. Throws InputError naming a recording it cannot run,
/// std::invalid_argument ("--fit: ...") for a fit request it cannot run; a least-squares fit that
/// does not converge and a rollout that fails come back as ok = false.
RolloutRun Rollout(const Experiment& experiment, std::vector<MarkerRecording> recordings,
                      const RolloutRunOptions& options = {});

}  // namespace rodfit
