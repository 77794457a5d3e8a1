// Motion-capture recordings of tracked markers (docs/formats.md, "Recordings"): a long CSV with
// one row per marker and frame, `frame,marker,x,y,z` (with a frame rate) or `t,marker,x,y,z`
// (evenly spaced times, up to 10 % jitter). Dropped samples are rows that are absent or
// coordinates that are empty or `nan`.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace rodfit {

struct MarkerRecording {
  std::string file;
  double frame_interval = 0.0;              ///< [s]
  std::vector<Eigen::Matrix3Xd> frames;     ///< 3 x markers per frame [m], NaN where not seen
};

/// Reads a recording; `frame_rate` [Hz] is required with a `frame` column, and with `t` (when
/// positive) must agree with the times within 1 %; positions are multiplied by
/// `position_scale` [m per file unit] (1e-3 for millimetres). A `t` column's times may jitter
/// by up to 10 % of the frame interval: frame k is taken at its nominal time (the interval
/// fitted to the times, or 1 / frame_rate). Throws InputError naming the file, line and column
/// (markers not 0..M-1 integers, a frame seen twice for one marker, a coordinate that is not a
/// number, empty or nan, irregular times, more than 100,000 frames or 10,000 markers, markers
/// out of order along the rod in frame 0, a frame interval above kMaxFrameInterval).
/// Longest frame interval a recording may have [s]: motion capture runs at tens to thousands of
/// hertz; an interval above a second is times in milliseconds read as seconds (or a frame rate
/// in frames per minute), and would have the rollout take thousands of steps per frame.
inline constexpr double kMaxFrameInterval = 1.0;

MarkerRecording ReadMarkerRecording(const std::string& path, double frame_rate,
                                    double position_scale = 1.0);

/// The recording's units against the rod: throws InputError naming the file when its markers
/// span (bounding-box diagonal over all frames) more than 100 rod lengths, the mark of
/// millimetres read as metres, or less than a hundredth of the rod (two markers or more seen in
/// the first frame; metres read as millimetres), with the hint `hint` (e.g. the option that sets the unit).
void CheckRecordingScale(const MarkerRecording& recording, double rod_length,
                         const std::string& hint);

/// The largest stretch of the rod a recording may show [-]: a frame's marker polyline longer
/// than (1 + this) rod lengths, or a first frame's shorter than (1 - this), is not a recording
/// of this rod (another rod, a scaled or mislabelled recording).
inline constexpr double kRecordingLengthTolerance = 0.2;

/// The recording against the rod it is to be a recording of: throws InputError naming the file
/// and the frame when the first frame's marker polyline (its seen markers in order) is not
/// within kRecordingLengthTolerance of `rod_length` (the rollout places the markers on the rod
/// by it), or a later frame's is longer than (1 + kRecordingLengthTolerance) rod lengths (the
/// rod would be stretched beyond anything a rod model describes).
void CheckRecordingFitsRod(const MarkerRecording& recording, double rod_length);

/// The fitted values of a `rollout --fit` result file (motion_fit.json, docs/cli.md,
/// "rollout"): per parameter name, its `value` in SI units, in the file's order. Throws
/// InputError naming the file, the line and the key for a file that cannot be read or is not
/// JSON, no `parameters` object, a name that is not a row of a moving thread's model
/// (InMotionModel, rodfit/model/material_parameters.h), or a value that is not a number > 0.
std::vector<std::pair<std::string, double>> ReadMotionFitValues(const std::string& path);

/// The fitted rest shape of a motion_fit.json (`rest_shape`: knots s_m [m] and k1_per_m,
/// k2_per_m, tau_per_m [1/m] per knot), as RodSpec::rest_curvature_s / rest_curvature_profile.
/// False when the file has none; throws InputError naming the file, line and key for lists that
/// are not finite numbers of one length (>= 2) or knots not strictly increasing within
/// [0, rod_length].
bool ReadMotionFitRestShape(const std::string& path, double rod_length, std::vector<double>* s,
                            std::vector<Eigen::Vector3d>* profile);

}  // namespace rodfit
