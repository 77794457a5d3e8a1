// One updating status line on a terminal for work that lasts longer than about a second (the
// fit's iterations; sequences and benchmarks): the caller's text, the elapsed time and, when the
// work's size is known, an ETA from the rate so far, redrawn in place with a carriage return.
// Nothing at all is written when the stream is not a terminal (a log file, a pipe, CI) or when
// the user asked for quiet (`-q`), so that captured stderr holds only messages.
#pragma once

#include <chrono>
#include <limits>
#include <string>

namespace rodfit {

class ProgressLine {
 public:
  struct Options {
    double delay_seconds = 1.0;     ///< nothing is shown before this: short work stays silent
    double interval_seconds = 0.1;  ///< at most one redraw per interval (the last text wins)
  };

  /// Draws on file descriptor `fd` (2: stderr) only when !quiet and `fd` is a terminal.
  explicit ProgressLine(bool quiet, int fd = 2);
  ProgressLine(bool quiet, int fd, Options options);
  /// Finish().
  ~ProgressLine();
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  /// False when nothing will ever be drawn (quiet, or not a terminal).
  bool enabled() const { return enabled_; }

  /// Shows `text` (e.g. "iteration 7  cost 1.25e+02"), followed by the elapsed time and, for
  /// `fraction_done` in (0, 1], the estimated time left. NaN: the work's size is unknown (no
  /// ETA). Not thread-safe: call it from one thread.
  void Update(const std::string& text,
              double fraction_done = std::numeric_limits<double>::quiet_NaN());

  /// Erases the line if one was drawn, so that the next output starts at a clean line start.
  void Finish();

  /// "0.4 s", "12 s", "3 min 05 s", "2 h 03 min": a duration for the line.
  static std::string FormatDuration(double seconds);

 private:
  using Clock = std::chrono::steady_clock;
  void Write(const std::string& bytes) const;

  int fd_;
  bool enabled_;
  Options options_;
  Clock::time_point start_;
  Clock::time_point last_draw_{};
  bool drawn_ = false;
  size_t drawn_width_ = 0;  // characters on the line now, to erase it
};

}  // namespace rodfit
