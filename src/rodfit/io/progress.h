// Progress for work that lasts longer than about a second (the fit's iterations; moving scenes'
// steps; sequences and benchmarks): the caller's text, the elapsed time and, when the work's size
// is known, an ETA from the rate so far. On a terminal, one status line redrawn in place with a
// carriage return. On anything else (a log file, a pipe, CI) only work that lasts longer than a
// few seconds says anything: plain lines, "rodfit: progress: TEXT  ELAPSED  ETA ...", one
// every few seconds, so that a long run's log shows it is alive and a short run's stderr holds only its
// messages. Nothing at all when the user asked for quiet (`-q`).
#pragma once

#include <chrono>
#include <limits>
#include <string>

namespace rodfit {

/// How a plain progress line starts: a reader of a log (or a test of the messages) tells them
/// from the messages by it.
inline constexpr const char* kPlainProgressPrefix = "rodfit: progress: ";

class ProgressLine {
 public:
  struct Options {
    double delay_seconds = 1.0;     ///< nothing is shown before this: short work stays silent
    double interval_seconds = 0.1;  ///< at most one redraw per interval (the last text wins)
    /// Not a terminal: the first plain line after this, and at most one line per interval.
    double plain_delay_seconds = 5.0;
    double plain_interval_seconds = 5.0;
  };

  /// Draws on file descriptor `fd` (2: stderr) when !quiet: a status line on a terminal, plain
  /// lines on anything else.
  explicit ProgressLine(bool quiet, int fd = 2);
  ProgressLine(bool quiet, int fd, Options options);
  /// Finish().
  ~ProgressLine();
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  /// The terminal's status line is drawn (not quiet, and a terminal).
  bool enabled() const { return enabled_; }
  /// Plain lines are written instead (not quiet, and not a terminal). Callers hand Update their
  /// progress when enabled() || plain().
  bool plain() const { return plain_; }

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
  bool plain_;
  Options options_;
  Clock::time_point start_;
  Clock::time_point last_draw_{};
  bool drawn_ = false;
  size_t drawn_width_ = 0;  // characters on the line now, to erase it
};

}  // namespace rodfit
