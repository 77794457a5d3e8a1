// The error model (docs/architecture.md, "Errors"), in three kinds:
//   - bad user data (a file, a line, a key): InputError (rodfit/io/errors.h), raised only where
//     the data is read, so that its message names the place;
//   - a broken API precondition (an argument a caller should not have passed): RODFIT_CHECK_ARG
//     below, std::invalid_argument with one line saying what is wrong;
//   - a broken internal invariant: assert (a bug, not an input).
// The CLI turns the first two into one line on stderr and a non-zero exit, in one place
// (src/cli/cli_common.cc, RunReportingErrors).
#pragma once

#include <stdexcept>
#include <string>

/// Throws std::invalid_argument(message) unless `condition` holds. `message` is evaluated only
/// when the condition fails, so it may build a string.
#define RODFIT_CHECK_ARG(condition, message)                        \
  do {                                                              \
    if (!(condition)) throw std::invalid_argument(std::string(message)); \
  } while (false)
