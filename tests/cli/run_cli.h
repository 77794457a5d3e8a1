// Runs the built `rodfit` binary (RODFIT_CLI) for the CLI tests, with stdout and stderr
// captured in files of a test's temporary directory.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "../io/temp_dir.h"

namespace rodfit::test {

struct RunResult {
  int status = -1;  // exit status, -1 when the program did not exit normally
  std::string out, err;
};

/// `text` (a run's stderr) without its plain progress lines (io/progress.h): a run that lasts
/// longer than a few seconds — any, on a loaded machine or under the sanitizers — writes them
/// when stderr is a file, and the tests check its messages.
inline std::string WithoutProgress(const std::string& text) {
  std::string out;
  size_t at = 0;
  while (at < text.size()) {
    size_t end = text.find('\n', at);
    end = end == std::string::npos ? text.size() : end + 1;
    if (text.compare(at, 18, "rodfit: progress: ") != 0) out.append(text, at, end - at);
    at = end;
  }
  return out;
}

/// `rodfit ARGS` (ARGS already shell-quoted where needed).
inline RunResult RunRodfit(const TempDir& dir, const std::string& args) {
  const std::string out = dir.File("stdout.txt"), err = dir.File("stderr.txt");
  const int raw = std::system(
      (std::string("'") + RODFIT_CLI + "' " + args + " >'" + out + "' 2>'" + err + "'").c_str());
  RunResult run;
  run.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  run.out = ReadText(out);
  run.err = WithoutProgress(ReadText(err));
  return run;
}

/// A path or word single-quoted for the shell.
inline std::string Quote(const std::string& s) { return "'" + s + "'"; }

/// `text` with the first `from` replaced by `to`; a test failure when `from` is not there (so a
/// bad-input test cannot pass on an unchanged, valid file).
inline std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  if (at == std::string::npos) {
    ADD_FAILURE() << "'" << from << "' not in the text";
    return text;
  }
  return text.replace(at, from.size(), to);
}

}  // namespace rodfit::test
