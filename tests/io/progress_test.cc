// The progress line (src/rodfit/io/progress.h): silent when its descriptor is not a terminal or
// when quiet, an updating line with carriage returns on a terminal (a pseudo-terminal here), an
// ETA only when the work's size is known, and nothing before the delay.
#include "rodfit/io/progress.h"

#include <algorithm>
#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace rodfit {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

// Everything readable from `fd` within `timeout_ms`.
std::string Drain(int fd, int timeout_ms = 200) {
  std::string out;
  char buffer[4096];
  for (;;) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, timeout_ms) <= 0 || !(p.revents & POLLIN)) break;
    const ssize_t n = read(fd, buffer, sizeof(buffer));
    if (n <= 0) break;
    out.append(buffer, static_cast<size_t>(n));
    timeout_ms = 50;
  }
  return out;
}

// A pseudo-terminal: the progress line writes to `slave`, the test reads `master`.
class Pty {
 public:
  Pty() {
    master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0) return;
    slave = open(ptsname(master), O_RDWR | O_NOCTTY);
  }
  ~Pty() {
    if (slave >= 0) close(slave);
    if (master >= 0) close(master);
  }
  bool ok() const { return master >= 0 && slave >= 0; }
  int master = -1, slave = -1;
};

ProgressLine::Options Immediate() {
  ProgressLine::Options o;
  o.delay_seconds = 0.0;
  o.interval_seconds = 0.0;
  return o;
}

TEST(ProgressLine, SilentWhenTheDescriptorIsNotATerminal) {
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  {
    ProgressLine progress(/*quiet=*/false, fds[1], Immediate());
    EXPECT_FALSE(progress.enabled());
    progress.Update("iteration 1  cost 3.0e+00", 0.5);
    progress.Update("iteration 2  cost 1.0e+00");
    progress.Finish();
  }  // the destructor writes nothing either
  close(fds[1]);
  EXPECT_EQ(Drain(fds[0]), "");
  close(fds[0]);

  std::FILE* file = std::tmpfile();
  ASSERT_NE(file, nullptr);
  {
    ProgressLine progress(false, fileno(file), Immediate());
    EXPECT_FALSE(progress.enabled());
    progress.Update("iteration 1");
  }
  std::fseek(file, 0, SEEK_END);
  EXPECT_EQ(std::ftell(file), 0L);
  std::fclose(file);
}

// Not a terminal (a log, a pipe, CI): after the plain delay, plain lines "rodfit: progress: TEXT  ELAPSED
// [ETA ...]" each ended by a newline, at most one per plain interval, none erased; quiet: none.
TEST(ProgressLine, PlainLinesWhenNotATerminalAfterTheDelay) {
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  ProgressLine::Options options = Immediate();
  options.plain_delay_seconds = 0.0;
  options.plain_interval_seconds = 0.0;
  {
    ProgressLine progress(/*quiet=*/false, fds[1], options);
    EXPECT_FALSE(progress.enabled());
    EXPECT_TRUE(progress.plain());
    progress.Update("simulate: 40 % (case swing, t = 0.4 s of 1 s)", 0.4);
    progress.Update("simulate: 80 % (case swing, t = 0.8 s of 1 s)");
    progress.Finish();
  }
  close(fds[1]);
  const std::string out = Drain(fds[0]);
  close(fds[0]);
  EXPECT_THAT(out, StartsWith("rodfit: progress: simulate: 40 % (case swing, t = 0.4 s of 1 s)  "));
  EXPECT_THAT(out, HasSubstr("ETA "));
  EXPECT_THAT(out, HasSubstr("\nrodfit: progress: simulate: 80 % (case swing, t = 0.8 s of 1 s)  "));
  EXPECT_THAT(out, Not(HasSubstr("\r")));
  ASSERT_FALSE(out.empty());
  EXPECT_EQ(out.back(), '\n');
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 2);

  // One line per interval: the second update within it is dropped.
  ASSERT_EQ(pipe(fds), 0);
  options.plain_interval_seconds = 3600.0;
  {
    ProgressLine progress(false, fds[1], options);
    progress.Update("step 1");
    progress.Update("step 2");
  }
  close(fds[1]);
  const std::string one = Drain(fds[0]);
  close(fds[0]);
  EXPECT_THAT(one, StartsWith("rodfit: progress: step 1  "));
  EXPECT_EQ(std::count(one.begin(), one.end(), '\n'), 1) << one;
}

TEST(ProgressLine, SilentOnATerminalWhenQuiet) {
  Pty pty;
  ASSERT_TRUE(pty.ok());
  {
    ProgressLine progress(/*quiet=*/true, pty.slave, Immediate());
    EXPECT_FALSE(progress.enabled());
    progress.Update("iteration 1", 0.5);
  }
  EXPECT_EQ(Drain(pty.master), "");
}

TEST(ProgressLine, OneUpdatingLineOnATerminal) {
  Pty pty;
  ASSERT_TRUE(pty.ok());
  ProgressLine progress(false, pty.slave, Immediate());
  EXPECT_TRUE(progress.enabled());
  progress.Update("iteration 12  cost 1.25e+02");
  std::string out = Drain(pty.master);
  EXPECT_THAT(out, StartsWith("\riteration 12  cost 1.25e+02  "));
  EXPECT_THAT(out, HasSubstr(" s"));  // the elapsed time
  EXPECT_THAT(out, Not(HasSubstr("ETA")));  // unknown size: no ETA
  EXPECT_THAT(out, Not(HasSubstr("\n")));

  // A shorter text overwrites the longer one's tail with spaces; a known fraction gives an ETA.
  progress.Update("frame 5/10", 0.5);
  out = Drain(pty.master);
  EXPECT_THAT(out, StartsWith("\rframe 5/10  "));
  EXPECT_THAT(out, HasSubstr("ETA "));
  EXPECT_THAT(out, Not(HasSubstr("\n")));

  // Finish erases the line and returns to its start.
  progress.Finish();
  out = Drain(pty.master);
  ASSERT_GE(out.size(), 2u);
  EXPECT_EQ(out.front(), '\r');
  EXPECT_EQ(out.back(), '\r');
  EXPECT_EQ(out.find_first_not_of(' ', 1), out.size() - 1) << "only spaces between the returns";
  progress.Finish();  // nothing more to erase
  EXPECT_EQ(Drain(pty.master, 50), "");
}

TEST(ProgressLine, NothingBeforeTheDelay) {
  Pty pty;
  ASSERT_TRUE(pty.ok());
  ProgressLine::Options options;
  options.delay_seconds = 3600.0;  // no test takes an hour: short work stays silent
  {
    ProgressLine progress(false, pty.slave, options);
    EXPECT_TRUE(progress.enabled());
    progress.Update("iteration 1", 0.9);
  }
  EXPECT_EQ(Drain(pty.master, 50), "");
}

TEST(ProgressLine, DurationsAreReadable) {
  EXPECT_EQ(ProgressLine::FormatDuration(0.42), "0.4 s");
  EXPECT_EQ(ProgressLine::FormatDuration(12.4), "12 s");
  EXPECT_EQ(ProgressLine::FormatDuration(185), "3 min 05 s");
  EXPECT_EQ(ProgressLine::FormatDuration(7380), "2 h 03 min");
  EXPECT_EQ(ProgressLine::FormatDuration(-1), "?");
}

}  // namespace
}  // namespace rodfit
