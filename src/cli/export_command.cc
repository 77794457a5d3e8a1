// `rodfit export PROFILE --format FORMAT -o FILE`: a fitted profile in the terms of another engine
// (rodfit/runtime/export.h: the formats are a registry), validated before anything is written and
// written by the output rule of every command (io/output_dir.h): staged beside the target and
// renamed into place, never over an input, a directory, a device or a FIFO, never to an empty path.
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/runtime/export.h"
#include "rodfit/runtime/profile.h"

int RunExport(int argc, char** argv) {
  std::string description =
      "Export a fitted profile for another simulator. Formats (docs/formats.md, \"Exports\"):";
  std::vector<std::string> names;
  for (const rodfit::ExportFormat& f : rodfit::ExportFormats()) {
    description += std::string(" ") + f.name + ": " + f.summary + ";";
    names.push_back(f.name);
  }
  description.back() = '.';
  CLI::App app(description, "rodfit export");
  std::string profile_path, format_name, output;
  double time_step = 0.0;
  std::vector<std::string> sets;
  app.add_option("profile", profile_path, "profile JSON (rodfit fit)")->required();
  app.add_option("--format", format_name, "one of the formats above")
      ->required()
      ->check(CLI::IsMember(names));
  app.add_option("-o,--output", output, "output file (written atomically)")->required();
  app.add_option("--time-step", time_step,
                 "[s] the simulator's (sub)step: xpbd requires it; sofa and mujoco write it "
                 "(default 1e-3 s, mujoco less when its cable needs less)")
      ->check(FiniteRange(1e-9, 10.0));
  app.add_option("--set", sets,
                 "NAME=VALUE [SI]: a value for a parameter the profile leaves undetermined "
                 "(not json; repeatable)");
  // CLI11's errors are exit 1 with one line, as every command's (cli_common.h, docs/cli.md).
  if (const int status = Parse(app, argc, argv); status >= 0) return status;
  const rodfit::ExportFormat& format = *rodfit::FindExportFormat(format_name);
  if (!format.takes_overrides && !sets.empty())
    throw std::invalid_argument(std::string("--set is not for --format ") + format.name +
                                " (it writes the profile as fitted)");
  rodfit::ProfileReadOptions read;
  for (const std::string& set : sets) {
    std::string why;
    if (!rodfit::ParseOverride(set, &read.overrides, &why)) throw std::invalid_argument("--set " + why);
  }
  // The output rule, checked before the profile is even read: a file name in a folder, not an
  // input of the run; what is at the path now (a directory, device, FIFO) is refused by the
  // commit below, before anything is moved.
  const std::filesystem::path target(output);
  if (output.empty()) throw std::invalid_argument("-o is empty: give the output file's path");
  if (!target.has_filename() || target.filename() == "." || target.filename() == "..")
    throw rodfit::InputError(output, 0, "", "is not a file name (-o names the output file)");
  rodfit::CheckOutputFile(output, {{profile_path, "the profile"}});
  // One read of the file: the json format re-writes exactly the text that was validated.
  const std::string text =
      rodfit::ReadInputFile(profile_path, "a profile", rodfit::kMaxProfileBytes);
  const rodfit::Profile profile = rodfit::ParseProfile(text, profile_path, read);
  rodfit::ExportOptions options;
  options.time_step = time_step;
  const std::string exported = rodfit::Export(format, {profile, text, options});
  rodfit::StagedDirectory folder(target.has_parent_path() ? target.parent_path().string()
                                                          : std::string("."),
                                 /*stage_inside=*/true);
  folder.Write(target.filename().string(), exported, "output file name");
  folder.Commit();
  std::cout << "wrote " << output << "\n";
  return EXIT_SUCCESS;
}
