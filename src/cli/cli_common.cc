// What the executable and the commands module share (cli_common.h).
#include "cli_common.h"

#include <cstdlib>
#include <exception>
#include <iostream>
#include <new>

#include <CLI/CLI.hpp>

int Parse(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help
    std::cerr << app.get_name() << ": " << OneLine(e.what()) << " (see --help)\n";
    return EXIT_FAILURE;
  }
  return -1;
}

int RunReportingErrors(const char* name, int (*run)(int argc, char** argv), int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::bad_alloc&) {
    // Inputs within every documented limit can still ask for more memory than there is.
    std::cerr << "rodfit: out of memory while running " << name
              << " (inputs or limits too large for this machine)\n";
    return EXIT_FAILURE;
  } catch (const std::exception& e) {
    std::cerr << "rodfit: " << OneLine(e.what()) << "\n";
    return EXIT_FAILURE;
  }
}
