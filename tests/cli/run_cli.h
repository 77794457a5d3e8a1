// Runs the built `rodfit` binary (RODFIT_CLI) for the CLI tests, with stdout and stderr
// captured in files of a test's temporary directory.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <string>

#include "../io/temp_dir.h"

namespace rodfit::test {

struct RunResult {
  int status = -1;  // exit status, -1 when the program did not exit normally
  std::string out, err;
};

/// `rodfit ARGS` (ARGS already shell-quoted where needed).
inline RunResult RunRodfit(const TempDir& dir, const std::string& args) {
  const std::string out = dir.File("stdout.txt"), err = dir.File("stderr.txt");
  const int raw = std::system(
      (std::string("'") + RODFIT_CLI + "' " + args + " >'" + out + "' 2>'" + err + "'").c_str());
  RunResult run;
  run.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  run.out = ReadText(out);
  run.err = ReadText(err);
  return run;
}

/// A path or word single-quoted for the shell.
inline std::string Quote(const std::string& s) { return "'" + s + "'"; }

}  // namespace rodfit::test
