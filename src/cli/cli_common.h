// What every command shares, on both sides of the split between the `rodfit` executable and its
// commands module (docs/cli.md, "Start-up"): both compile cli_common.cc, so nothing here holds
// state that one side would need to see from the other.
#pragma once

#include <string>

#include "rodfit/io/errors.h"

namespace CLI {
class App;
}

// OneLine and CasePlace are the library's (rodfit/io/errors.h).
using rodfit::CasePlace;
using rodfit::OneLine;

/// Parses argv for one subcommand; returns -1 to go on, else the exit status (help or error).
int Parse(CLI::App& app, int argc, char** argv);

/// Runs the command `name` and turns what it throws into one line on stderr and exit status 1:
/// out of memory named as such, any other exception by its message.
int RunReportingErrors(const char* name, int (*run)(int argc, char** argv), int argc, char** argv);
