#include "rodfit/io/recording.h"

#include <cmath>
#include <cstdio>
#include <limits>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"

namespace rodfit {

MarkerRecording ReadMarkerRecording(const std::string& path, double frame_rate,
                                    double position_scale) {
  constexpr int kMaxFrames = 100000, kMaxMarkers = 10000;
  const CsvTable table = CsvTable::Read(path);
  MarkerRecording rec;
  rec.file = path;
  if (table.num_rows() < 1) throw InputError(path, 0, "", "no rows");
  if (table.HasColumn("case")) {
    // simulate --markers writes one recording per case into one file: one case per rollout.
    const std::vector<std::string> cases = table.TextColumn("case");
    for (int r = 1; r < table.num_rows(); ++r)
      if (cases[r] != cases[0])
        throw InputError(path, table.line(r), "case",
                         "a second case (" + ClipForMessage(cases[r]) +
                             "): a recording holds one case; split the file by its case column");
  }
  const bool by_frame = table.HasColumn("frame");
  if (!by_frame && !table.HasColumn("t"))
    throw InputError(path, 1, "frame", "needs a frame column (with --frame-rate) or a t column");
  const std::vector<double> key = table.Column(by_frame ? "frame" : "t");
  const std::vector<double> marker = table.Column("marker"), x = table.Column("x"),
                            y = table.Column("y"), z = table.Column("z");
  std::vector<long> frame_of(table.num_rows());
  int markers = 0;
  long frames = 0;
  double t0 = 0.0;
  if (!by_frame) {
    // Evenly spaced times: the interval is the smallest positive difference between times.
    t0 = key[0];
    double dt = std::numeric_limits<double>::infinity();
    for (int r = 0; r < table.num_rows(); ++r) {
      t0 = std::min(t0, key[r]);
      for (int q = r + 1; q < table.num_rows() && q < r + 100000; ++q) {
        const double d = std::abs(key[q] - key[r]);
        if (d > 0.0 && d < dt) dt = d;
        if (d > 0.0) break;
      }
    }
    if (!std::isfinite(dt)) throw InputError(path, table.line(0), "t", "needs at least 2 times");
    rec.frame_interval = dt;
  } else {
    if (!(frame_rate > 0.0)) throw InputError(path, 1, "frame", "a frame column needs --frame-rate");
    rec.frame_interval = 1.0 / frame_rate;
  }
  for (int r = 0; r < table.num_rows(); ++r) {
    double f = by_frame ? key[r] : (key[r] - t0) / rec.frame_interval;
    if (std::abs(f - std::round(f)) > 1e-6 || f < 0 || f >= kMaxFrames)
      throw InputError(path, table.line(r), by_frame ? "frame" : "t",
                       by_frame ? "must be an integer in [0, 100000)"
                                : "times must be evenly spaced (a multiple of the smallest step)");
    frame_of[r] = std::lround(f);
    if (marker[r] != std::round(marker[r]) || marker[r] < 0 || marker[r] >= kMaxMarkers)
      throw InputError(path, table.line(r), "marker", "must be an integer in [0, 10000)");
    markers = std::max(markers, static_cast<int>(marker[r]) + 1);
    frames = std::max(frames, frame_of[r] + 1);
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  rec.frames.assign(frames, Eigen::Matrix3Xd::Constant(3, markers, nan));
  for (int r = 0; r < table.num_rows(); ++r) {
    Eigen::Matrix3Xd& fr = rec.frames[frame_of[r]];
    const int m = static_cast<int>(marker[r]);
    if (fr.col(m).allFinite())
      throw InputError(path, table.line(r), "marker", "this marker is given twice in one frame");
    fr.col(m) = position_scale * Eigen::Vector3d(x[r], y[r], z[r]);
  }
  return rec;
}

void CheckRecordingScale(const MarkerRecording& recording, double rod_length,
                         const std::string& hint) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const Eigen::Matrix3Xd& frame : recording.frames) {
    for (int m = 0; m < frame.cols(); ++m) {
      if (!frame.col(m).allFinite()) continue;
      lo = lo.cwiseMin(frame.col(m));
      hi = hi.cwiseMax(frame.col(m));
    }
  }
  if (!(hi.x() >= lo.x())) return;  // no marker seen: the rollout says so
  const double span = (hi - lo).norm();
  if (span > 100.0 * rod_length) {
    char text[256];
    std::snprintf(text, sizeof(text),
                  "the markers span %.4g m, more than 100 rod lengths (the rod is %.4g m): "
                  "millimetres read as metres? (%s)",
                  span, rod_length, hint.c_str());
    throw InputError(recording.file, 0, "x", text);
  }
  int seen = 0;
  for (int m = 0; m < recording.frames.front().cols(); ++m)
    seen += recording.frames.front().col(m).allFinite() ? 1 : 0;
  if (seen >= 2 && span < 0.01 * rod_length) {
    char text[256];
    std::snprintf(text, sizeof(text),
                  "the markers span %.4g m, less than a hundredth of the rod (%.4g m): metres "
                  "read as millimetres? (%s)",
                  span, rod_length, hint.c_str());
    throw InputError(recording.file, 0, "x", text);
  }
}

}  // namespace rodfit
