// Progress line (progress.h). Written with write(2) on the descriptor: stderr is unbuffered
// anyway, and the line never sits in a stdio buffer behind later messages.
#include "rodfit/io/progress.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>

namespace rodfit {
namespace {

// The terminal's width less one column (a line that fills the last column wraps on some
// terminals, and then "\r" no longer returns to its start); 80 columns when unknown.
size_t UsableColumns(int fd) {
  winsize ws{};
  if (ioctl(fd, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 10) return ws.ws_col - 1;
  return 79;
}

// The number of characters (UTF-8 code points) in `s`, for the erase width.
size_t Columns(const std::string& s) {
  size_t n = 0;
  for (unsigned char c : s)
    if ((c & 0xC0) != 0x80) ++n;
  return n;
}

}  // namespace

ProgressLine::ProgressLine(bool quiet, int fd) : ProgressLine(quiet, fd, Options()) {}

ProgressLine::ProgressLine(bool quiet, int fd, Options options)
    : fd_(fd),
      enabled_(!quiet && isatty(fd) == 1),
      plain_(!quiet && isatty(fd) != 1),
      options_(options),
      start_(Clock::now()) {}

ProgressLine::~ProgressLine() { Finish(); }

std::string ProgressLine::FormatDuration(double seconds) {
  char b[48];
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  if (seconds < 10) {
    std::snprintf(b, sizeof(b), "%.1f s", seconds);
  } else if (seconds < 60) {
    std::snprintf(b, sizeof(b), "%.0f s", seconds);
  } else if (seconds < 3600) {
    const long s = std::lround(seconds);
    std::snprintf(b, sizeof(b), "%ld min %02ld s", s / 60, s % 60);
  } else {
    const long m = std::lround(seconds / 60);
    std::snprintf(b, sizeof(b), "%ld h %02ld min", m / 60, m % 60);
  }
  return b;
}

void ProgressLine::Update(const std::string& text, double fraction_done) {
  if (!enabled_ && !plain_) return;
  const Clock::time_point now = Clock::now();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  if (elapsed < options_.delay_seconds) return;
  if (drawn_ && std::chrono::duration<double>(now - last_draw_).count() < options_.interval_seconds)
    return;
  if (plain_) {
    // A log: one plain line every few seconds once the work has lasted a few seconds.
    if (elapsed < options_.plain_delay_seconds) return;
    if (drawn_ &&
        std::chrono::duration<double>(now - last_draw_).count() < options_.plain_interval_seconds)
      return;
    std::string line = kPlainProgressPrefix + text + "  " + FormatDuration(elapsed);
    if (std::isfinite(fraction_done) && fraction_done >= 0.01 && fraction_done <= 1.0)
      line += "  ETA " + FormatDuration(elapsed * (1.0 - fraction_done) / fraction_done);
    for (char& c : line)
      if (c == '\n' || c == '\r') c = ' ';
    Write(line + "\n");
    drawn_ = true;  // Finish() erases nothing: drawn_width_ stays 0
    last_draw_ = now;
    return;
  }
  std::string line = text + "  " + FormatDuration(elapsed);
  // An ETA only once enough of the work is done for the rate to mean something.
  if (std::isfinite(fraction_done) && fraction_done >= 0.01 && fraction_done <= 1.0)
    line += "  ETA " + FormatDuration(elapsed * (1.0 - fraction_done) / fraction_done);
  const size_t columns = UsableColumns(fd_);
  if (Columns(line) > columns) {  // cut at a character boundary
    size_t n = 0, i = 0;
    for (; i < line.size(); ++i) {
      if ((static_cast<unsigned char>(line[i]) & 0xC0) != 0x80 && n++ == columns) break;
    }
    line.resize(i);
  }
  const size_t width = Columns(line);
  std::string out = "\r" + line;
  if (width < drawn_width_) out += std::string(drawn_width_ - width, ' ');  // old text's tail
  Write(out);
  drawn_ = true;
  drawn_width_ = width;
  last_draw_ = now;
}

void ProgressLine::Finish() {
  if (!drawn_ || plain_) return;  // plain lines stay, each ended
  Write("\r" + std::string(drawn_width_, ' ') + "\r");
  drawn_ = false;
  drawn_width_ = 0;
}

void ProgressLine::Write(const std::string& bytes) const {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;  // a progress line is not worth an error
    done += static_cast<size_t>(n);
  }
}

}  // namespace rodfit
