// The rodfit command (DESIGN.md §6): a thin table of subcommands in the manner of COLMAP's
// `commands.emplace_back("name", &RunName)`. Each Run* parses its options with CLI11, calls the
// library and turns a failure into one line on stderr and a non-zero exit. No physics here.
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "rodfit/io/csv.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/shapes_csv.h"
#include "rodfit/model/rod.h"
#include "rodfit/solve/statics.h"

namespace {

std::string OneLine(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

// Parses argv for one subcommand; returns -1 to go on, else the exit status (help or error).
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

int RunSimulate(int argc, char** argv) {
  CLI::App app(
      "Solve every load case of a scene to static equilibrium and write "
      "DIR/shapes.csv (case,vertex,s,x,y,z).",
      "rodfit simulate");
  std::string scene_path, output_dir;
  app.add_option("scene", scene_path, "scene YAML (DESIGN.md §6)")->required();
  app.add_option("-o,--output", output_dir, "output directory, created if missing")->required();
  if (const int status = Parse(app, argc, argv); status >= 0) return status;

  const rodfit::Experiment experiment = rodfit::LoadExperiment(scene_path);
  const rodfit::Scene& scene = experiment.scene;
  std::vector<rodfit::CaseShape> shapes;
  for (const rodfit::LoadCase& load_case : scene.cases) {
    rodfit::RodModel model(scene.rod, scene.material, scene.gravity, load_case);
    rodfit::RodState state = model.StraightState();
    const rodfit::StaticsSummary summary =
        rodfit::SolveStatics(model, rodfit::StaticsOptions(), &state);
    if (!summary.converged) {
      std::cerr << "rodfit simulate: case " << load_case.name << ": " << OneLine(summary.reason)
                << "\n";
      return EXIT_FAILURE;
    }
    rodfit::CaseShape shape;
    shape.name = load_case.name;
    shape.x = state.x;
    for (int i = 0; i < model.num_vertices(); ++i) shape.s.push_back(model.arc_length(i));
    shapes.push_back(shape);
  }
  // Only after every case has converged, so a failed run leaves nothing behind.
  rodfit::CreateDirectories(output_dir);
  rodfit::WriteShapesCsv((std::filesystem::path(output_dir) / "shapes.csv").string(), shapes);
  return EXIT_SUCCESS;
}

struct Command {
  const char* name;
  const char* help;
  int (*run)(int argc, char** argv);
};

// fit, synth, extract and bench join this table as their layers land.
const std::vector<Command>& Commands() {
  static const std::vector<Command> commands = {
      {"simulate", "solve every case of a scene; write DIR/shapes.csv", &RunSimulate},
  };
  return commands;
}

void PrintUsage(std::ostream& out) {
  out << "Usage: rodfit COMMAND [OPTIONS]   (rodfit COMMAND --help for its options)\n\n"
      << "Commands:\n";
  for (const Command& c : Commands()) out << "  " << c.name << "    " << c.help << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << "rodfit: no command given (see rodfit --help)\n";
    return EXIT_FAILURE;
  }
  const std::string name = argv[1];
  if (name == "-h" || name == "--help" || name == "help") {
    PrintUsage(std::cout);
    return EXIT_SUCCESS;
  }
  for (const Command& c : Commands()) {
    if (name != c.name) continue;
    try {
      return c.run(argc - 1, argv + 1);
    } catch (const std::exception& e) {
      std::cerr << "rodfit: " << OneLine(e.what()) << "\n";
      return EXIT_FAILURE;
    }
  }
  std::cerr << "rodfit: unknown command '" << name << "' (see rodfit --help)\n";
  return EXIT_FAILURE;
}
