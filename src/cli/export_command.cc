// `rodfit export PROFILE --format sofa|xpbd|json -o FILE`: a fitted profile in the terms of
// another engine (rodfit/runtime/export.h), written atomically.
#include <cstdlib>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/runtime/export.h"
#include "rodfit/runtime/profile.h"

int RunExport(int argc, char** argv) {
  CLI::App app(
      "Export a fitted profile for another simulator: sofa (an XML scene snippet for SOFA's "
      "beam and Cosserat components), xpbd (per-segment compliances of a position-based stiff "
      "rod at --time-step, JSON) or json (the profile itself, validated). Fields and units: "
      "docs/formats.md, \"Exports\".",
      "rodfit export");
  std::string profile_path, format, output;
  double time_step = 0.0;
  std::vector<std::string> sets;
  app.add_option("profile", profile_path, "profile JSON (rodfit fit)")->required();
  app.add_option("--format", format, "sofa, xpbd or json")
      ->required()
      ->check(CLI::IsMember({"sofa", "xpbd", "json"}));
  app.add_option("-o,--output", output, "output file (written atomically)")->required();
  app.add_option("--time-step", time_step, "[s] xpbd: the simulator's (sub)step, > 0")
      ->check(CLI::Range(1e-9, 10.0));
  app.add_option("--set", sets,
                 "NAME=VALUE [SI]: a value for a parameter the profile leaves undetermined "
                 "(sofa, xpbd; repeatable)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);
    std::cerr << "rodfit export: " << e.what() << " (see --help)\n";
    return EXIT_FAILURE;
  }
  if (format == "xpbd" && !(time_step > 0.0))
    throw std::invalid_argument("export --format xpbd needs --time-step (the simulator's step [s])");
  if (format != "xpbd" && time_step > 0.0)
    throw std::invalid_argument("--time-step is for --format xpbd");
  if (format == "json" && !sets.empty())
    throw std::invalid_argument("--set is for sofa and xpbd (json writes the profile as fitted)");
  rodfit::ProfileReadOptions read;
  for (const std::string& set : sets) {
    std::string why;
    if (!rodfit::ParseOverride(set, &read.overrides, &why)) throw std::invalid_argument("--set " + why);
  }
  rodfit::RefuseOverwritingInput(output, {{profile_path, "the profile"}});
  // Validated whatever the format: an export of a broken profile would carry its mistakes on.
  const rodfit::Profile profile = rodfit::LoadProfile(profile_path, read);
  std::string text;
  if (format == "sofa") {
    text = rodfit::FormatSofaSnippet(profile);
  } else if (format == "xpbd") {
    text = rodfit::FormatXpbd(profile, time_step);
  } else {
    text = rodfit::FormatProfileCanonical(
        rodfit::ReadInputFile(profile_path, "a profile", rodfit::kMaxProfileBytes));
  }
  rodfit::WriteFileAtomically(output, text);
  std::cout << "wrote " << output << "\n";
  return EXIT_SUCCESS;
}
