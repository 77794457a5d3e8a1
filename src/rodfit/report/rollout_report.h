// The rollout report (`rodfit rollout ... --report DIR`; docs/cli.md, "rollout"): DIR/index.html,
// one self-contained page — the per-recording error table, the fitted parameters with their
// standard deviations, cost per iteration and timing when the run fitted them (`--fit`), and per
// recording an interactive 3-D view with a time slider over its frames (recorded and predicted
// markers), each marker's recorded and predicted path and the error over time — and its figures
// as SVG files in DIR/figures/.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/fit/motion_fit.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/pipeline/run.h"
#include "rodfit/solve/rollout.h"

namespace rodfit {

struct RolloutRecordingReport {
  std::string file;                       ///< the recording's path
  double frame_interval = 0.0;            ///< [s]
  std::vector<Eigen::Matrix3Xd> frames;   ///< recorded, 3 x markers per frame [m], NaN: not seen
  RolloutResult result;                   ///< the prediction
};

struct RolloutReportInput {
  std::string scene_path;
  std::vector<RolloutRecordingReport> recordings;
  /// With `rollout --fit`: the fit (else null) and what it fitted.
  const MotionFitResult* fit = nullptr;
  /// Every warning of the run, with what to do about it.
  std::vector<std::string> warnings;
};

/// Stages DIR/index.html and DIR/figures/*.svg in `out`. Returns the report's own warnings (e.g.
/// written without its 3-D views), which the caller prints.
std::vector<std::string> WriteRolloutReport(StagedDirectory* out, const RolloutReportInput& input);

/// The report of a rollout run (rodfit/pipeline/run.h): its recordings, results, fit and warnings
/// through WriteRolloutReport. What RolloutRunOptions::write_report takes, for the CLI and Python.
std::vector<std::string> WriteRolloutRunReport(StagedDirectory* out, const RolloutRun& run);

}  // namespace rodfit
