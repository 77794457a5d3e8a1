// The readers of observation sequence files the kinds share (docs/formats.md, "Observation
// sequences"): a centre-line entry's samples over time, one measurement per time at which
// something was seen, and a load cell's log, one reading per time. Internal to the pipeline.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>

#include "rodfit/fit/motion_fit.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/pipeline/sequence_input.h"

namespace rodfit {

/// One recorded sample of a sequence file: its time, arc length (markers) and coordinates.
struct SequenceSample {
  double t = 0.0, s = 0.0;
  Eigen::Vector3d value = Eigen::Vector3d::Zero();  ///< x, y, z [m] or u, v (and 0) [px]
};

/// Whether a sequence file has an s column: markers always, pixels when they are markers.
enum class SColumn { kNone, kOptional, kRequired };

/// The measurement of the samples seen at one time (`with_s`: the file has an s column).
using FrameMeasurement = std::shared_ptr<const Measurement> (*)(
    const KindContext& context, bool with_s, const std::vector<const SequenceSample*>& seen);

/// An entry's file as a sequence: columns `t` (or `frame` with the entry's frame_rate), `s` as
/// `s_column` says, then x,y,z or (`pixels`) u,v through the entry's camera; a coordinate left
/// empty or nan is a sample not seen. Throws InputError naming the file, the row's line and the
/// column (docs/formats.md lists the checks).
ObservationSequence ReadShapeSequence(const KindContext& context, bool pixels, SColumn s_column,
                                      FrameMeasurement frame_measurement);

/// A `reaction` entry's file as a sequence: a load cell's log `t,fx,fy,fz[,mx,my,mz]` (or
/// `frame,...` with the entry's frame_rate), one reading (ForceReadings) per row and time; a row
/// whose fields are all missing is a reading not taken.
ObservationSequence ReadReactionSequence(const KindContext& context);

}  // namespace rodfit
