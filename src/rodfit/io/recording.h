// Motion-capture recordings of tracked markers (docs/formats.md, "Recordings"): a long CSV with
// one row per marker and frame, `frame,marker,x,y,z` (with a frame rate) or `t,marker,x,y,z`
// (evenly spaced times). Dropped samples are rows that are absent.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace rodfit {

struct MarkerRecording {
  std::string file;
  double frame_interval = 0.0;              ///< [s]
  std::vector<Eigen::Matrix3Xd> frames;     ///< 3 x markers per frame [m], NaN where not seen
};

/// Reads a recording; `frame_rate` [Hz] is required with a `frame` column and ignored with `t`.
/// Throws InputError naming the file, line and column (markers not 0..M-1 integers, a frame
/// seen twice for one marker, uneven times, more than 100,000 frames or 10,000 markers).
MarkerRecording ReadMarkerRecording(const std::string& path, double frame_rate);

}  // namespace rodfit
