// The rodfit command (docs/cli.md): a thin table of subcommands in the manner of COLMAP's
// `commands.emplace_back("name", &RunName)`. Each Run* parses its options with CLI11, calls the
// library and turns a failure into one line on stderr and a non-zero exit. No physics here.
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Core>

#include "commands.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/image_observations.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/shapes_csv.h"
#include "rodfit/synth/synth.h"
#include "rodfit/io/errors.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/runtime/profile.h"
#include "rodfit/version.h"
#include "rodfit/vision/camera_file.h"
#include "rodfit/vision/centreline.h"

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

/// Strain above which `simulate` warns that an equilibrium is outside a rod model's range.
constexpr double kLargeStrain = 0.1;

int RunSimulate(int argc, char** argv) {
  CLI::App app(
      "Solve every load case of a scene to static equilibrium and write DIR/shapes.csv "
      "(case,vertex,s,x,y,z), DIR/forces.csv (the force and moment on every held point), "
      "DIR/summary.csv (how each solve ended); DIR/sections.csv and DIR/CASE.obj for poked "
      "cases. Cases that converge to an unstable equilibrium are warned about on stderr. "
      "A scene with a dynamics: block is integrated in time instead: DIR/trajectory.csv "
      "(case,t,vertex,s,x,y,z), DIR/reactions.csv (held points' forces over time), "
      "DIR/summary.csv.",
      "rodfit simulate");
  std::string scene_path, output_dir;
  bool keep_going = false;
  app.add_option("scene", scene_path, "scene YAML (docs/formats.md)")->required();
  app.add_option("-o,--output", output_dir, "output directory, created if missing")->required();
  MarkerSampling markers;
  app.add_option("--markers", markers.count,
                 "moving scene: also write DIR/markers.csv, a synthetic motion-capture recording "
                 "(t,marker,x,y,z) of this many markers evenly spaced in s, at every written frame")
      ->check(CLI::Range(2, 10000));
  app.add_option("--marker-noise", markers.noise, "[m] Gaussian noise per coordinate of markers.csv")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--marker-drop", markers.drop, "fraction of markers.csv samples dropped (not in frames 0-1)")
      ->check(CLI::Range(0.0, 0.9));
  app.add_option("--seed", markers.seed, "random seed of the marker noise and drops");
  app.add_flag("--keep-going", keep_going,
               "write the cases that converged and summary.csv even when one fails (exit 3)");
  std::string profile_path;
  std::vector<std::string> sets;
  app.add_option("--profile", profile_path,
                 "profile JSON (rodfit fit) whose parameters replace the scene's parameters: "
                 "block, which may then be left out; the scene's rod must be the profile's");
  app.add_option("--set", sets,
                 "NAME=VALUE [SI]: with --profile, a value for a parameter the profile leaves "
                 "undetermined (value null) or one to replace (repeatable)");
  if (const int status = Parse(app, argc, argv); status >= 0) return status;
  if (!sets.empty() && profile_path.empty())
    throw std::invalid_argument("--set needs --profile");

  rodfit::Experiment experiment =
      rodfit::LoadExperiment(scene_path, /*parameters_optional=*/!profile_path.empty());
  if (!profile_path.empty()) {
    rodfit::ProfileReadOptions read;
    for (const std::string& set : sets) {
      std::string why;
      if (!rodfit::ParseOverride(set, &read.overrides, &why))
        throw std::invalid_argument("--set " + why);
    }
    rodfit::UseProfileMaterial(rodfit::LoadProfile(profile_path, read), &experiment.scene);
  }
  if (experiment.scene.dynamics)
    return SimulateMotion(experiment, scene_path, output_dir, keep_going, markers);
  if (markers.count > 0)
    throw std::invalid_argument("--markers is for a moving scene (a dynamics: block)");
  const rodfit::Scene& scene = experiment.scene;
  std::vector<rodfit::CaseShape> shapes;
  std::vector<rodfit::CaseForce> forces;
  std::vector<rodfit::CaseSection> sections;
  std::vector<rodfit::CaseSummaryRow> summary;
  std::vector<std::pair<std::string, std::string>> meshes;  // case name, OBJ text
  std::vector<std::string> warnings;
  std::string first_failure;
  std::vector<rodfit::CaseSolution> solutions;
  solutions.reserve(scene.cases.size());
  for (size_t k = 0; k < scene.cases.size(); ++k) {
    const rodfit::LoadCase& load_case = scene.cases[k];
    const std::string where = "case " + load_case.name + ": ";
    rodfit::CaseSolution solution;
    try {
      solution = rodfit::SolveCase(scene, static_cast<int>(k),
                                   solutions.empty() ? nullptr : &solutions.back(),
                                   experiment.statics);
    } catch (const std::invalid_argument& e) {
      // The case is not a valid rod: name the case's entry in the file.
      throw rodfit::InputError(scene_path, experiment.cases[k].line,
                               "cases[" + std::to_string(k) + "]", e.what());
    }
    const rodfit::StaticsSummary& s = solution.summary;
    summary.push_back({load_case.name, s.converged, s.converged && s.stable, s.iterations,
                       s.gradient_norm, solution.seconds, s.reason});
    if (!s.converged) {
      if (first_failure.empty()) first_failure = where + OneLine(s.reason);
      solutions.push_back(std::move(solution));
      continue;
    }
    if (!s.stable)
      warnings.push_back("rodfit simulate: warning: " + where +
                         "the equilibrium found is unstable (a displacement the rod does not "
                         "resist); an experiment would not hold it");
    {
      // A rod model is a small-strain model: an equilibrium that stretches or compresses an edge by more than
      // 10 % (held points pulled apart, a unit mistake in EA) is reported, not silently returned.
      double strain = 0.0;
      const rodfit::RodModel& m = *solution.model;
      for (int j = 0; j < m.num_edges(); ++j)
        strain = std::max(strain, std::abs(solution.state.e.col(j).norm() /
                                               m.rest_edge_length(j) - 1.0));
      if (strain > kLargeStrain) {
        char percent[32];
        std::snprintf(percent, sizeof(percent), "%.3g", 100.0 * strain);
        warnings.push_back("rodfit simulate: warning: " + where + "an edge is strained by " +
                           percent + " %, beyond the small strains of a rod model (held points too far "
                           "apart? stretch_stiffness in the wrong unit?)");
      }
    }
    shapes.push_back({load_case.name, solution.shape_s, solution.shape});
    for (const rodfit::HeldReaction& r : solution.reactions)
      forces.push_back({load_case.name, r.point, r.s, r.position, r.force, r.moment});
    if (solution.poke) {
      const rodfit::PokeResult& poke = *solution.poke;
      if (!poke.ring.summary.IsUsable()) {
        if (first_failure.empty())
          first_failure = where + "cross-section: " + OneLine(poke.ring.summary.BriefReport());
        summary.back().converged = false;
        summary.back().reason = "cross-section: " + poke.ring.summary.BriefReport();
        solutions.push_back(std::move(solution));
        continue;
      }
      sections.push_back({load_case.name, poke.rest_world, poke.deformed_world});
      meshes.emplace_back(load_case.name, rodfit::FormatObj(rodfit::PokedTube(
                                              *solution.model, solution.state, *scene.section, poke)));
    }
    solutions.push_back(std::move(solution));
  }
  if (!first_failure.empty() && !keep_going) {
    std::cerr << "rodfit simulate: " << first_failure << "\n";
    return EXIT_FAILURE;
  }
  // Only now, and all files at once: a run that fails while writing (a full disk, a directory
  // where a file goes) leaves the output directory as it was.
  std::vector<std::pair<std::string, std::string>> files = {
      {"shapes.csv", rodfit::FormatShapesCsv(shapes)},
      {"forces.csv", rodfit::FormatForcesCsv(forces)},
      {"summary.csv", rodfit::FormatSummaryCsv(summary)}};
  if (!sections.empty()) files.emplace_back("sections.csv", rodfit::FormatSectionsCsv(sections));
  for (const auto& [name, obj] : meshes) files.emplace_back(name + ".obj", obj);
  rodfit::StagedDirectory out(output_dir);
  const std::vector<rodfit::InputFile> inputs = rodfit::ExperimentInputs(experiment);
  for (const auto& [name, text] : files) {
    // Case names become file names: the reader refuses paths, and Write keeps any name in DIR.
    out.Write(name, text, "case file name");
    rodfit::RefuseOverwritingInput(out.FinalPath(name), inputs);
  }
  out.Commit();
  // The time goes to stdout, not into a file: the same scene writes the same bytes.
  double seconds = 0.0;
  for (const rodfit::CaseSummaryRow& row : summary) seconds += row.seconds;
  std::printf("solved %zu cases in %.3f s; wrote %s\n", summary.size(), seconds,
              output_dir.c_str());
  for (const std::string& w : warnings) std::cerr << w << "\n";
  if (!first_failure.empty()) {
    std::cerr << "rodfit simulate: " << first_failure << " (other cases written)\n";
    return 3;
  }
  return EXIT_SUCCESS;
}

int RunSynth(int argc, char** argv) {
  CLI::App app(
      "Synthesize every observation file of an experiment from its parameter values (the "
      "truth); write them, DIR/experiment.yaml and DIR/truth.json.",
      "rodfit synth");
  std::string experiment_path, output_dir;
  std::uint32_t seed = 1;
  bool noise_free = false;
  app.add_option("experiment", experiment_path, "experiment YAML (docs/formats.md)")->required();
  app.add_option("-o,--output", output_dir, "output directory, created if missing")->required();
  app.add_option("--seed", seed, "random seed; the same seed gives the same bytes")
      ->default_val(1);
  app.add_flag("--noise-free", noise_free, "no noise, outliers or pixel noise (exact samples)");
  if (const int status = Parse(app, argc, argv); status >= 0) return status;

  const rodfit::Experiment experiment = rodfit::LoadExperiment(experiment_path);
  rodfit::SynthOptions options;
  options.seed = seed;
  options.add_noise = !noise_free;
  options.statics = experiment.statics;
  const rodfit::SynthBundle bundle = rodfit::Synthesize(experiment, output_dir, options);
  for (const std::string& line : bundle.report) std::cout << line << "\n";
  std::cout << "wrote " << bundle.files.size() << " files to " << output_dir << "\n";
  return EXIT_SUCCESS;
}

// "U,V" -> pixel; false when it is not two finite numbers.
bool ParsePixel(const std::string& text, Eigen::Vector2d* uv) {
  const size_t comma = text.find(',');
  if (comma == std::string::npos) return false;
  double u = 0.0, v = 0.0;
  if (!rodfit::ParseDouble(text.substr(0, comma), &u) ||
      !rodfit::ParseDouble(text.substr(comma + 1), &v)) {
    return false;
  }
  *uv = Eigen::Vector2d(u, v);
  return true;
}

int RunExtract(int argc, char** argv) {
  CLI::App app(
      "Extract the ordered centre-line of a thread from a camera image (writes u,v), or from two "
      "images of two calibrated cameras (writes triangulated x,y,z).",
      "rodfit extract");
  std::vector<std::string> images, camera_paths, starts, overlays;
  std::string stereo_path, output_path;
  app.add_option("images", images, "one image, or two images of two cameras")
      ->required()
      ->expected(1, 2);
  app.add_option("--camera", camera_paths, "camera file, one per image (docs/formats.md)");
  app.add_option("--stereo", stereo_path, "stereo calibration file holding both cameras");
  app.add_option("-o,--output", output_path, "output CSV: u,v (one image) or x,y,z (two)")
      ->required();
  app.add_option("--overlay", overlays, "image with the centre-line drawn, one per image");
  app.add_option("--start", starts, "U,V: start the centre-line at the end nearest this pixel, "
                                    "one per image");
  if (const int status = Parse(app, argc, argv); status >= 0) return status;

  const size_t n = images.size();
  auto fail = [](const std::string& why) {
    std::cerr << "rodfit extract: " << why << " (see --help)\n";
    return EXIT_FAILURE;
  };
  // No output may be one of the inputs (an overlay written over its own image).
  std::vector<rodfit::InputFile> inputs;
  for (const std::string& image : images) inputs.emplace_back(image, "an input image");
  for (const std::string& camera : camera_paths) inputs.emplace_back(camera, "a camera file");
  if (!stereo_path.empty()) inputs.emplace_back(stereo_path, "the stereo file");
  rodfit::RefuseOverwritingInput(output_path, inputs);
  for (const std::string& overlay : overlays) rodfit::RefuseOverwritingInput(overlay, inputs);

  std::vector<rodfit::Camera> cameras;
  if (!stereo_path.empty()) {
    if (n != 2 || !camera_paths.empty()) return fail("--stereo needs two images and no --camera");
    const auto pair = rodfit::LoadStereoCameras(stereo_path);
    cameras = {pair.first, pair.second};
  } else {
    if (camera_paths.size() != n) return fail("give one --camera per image, or --stereo");
    for (const std::string& path : camera_paths) cameras.push_back(rodfit::LoadCamera(path));
  }
  if (!starts.empty() && starts.size() != n) return fail("give one --start per image, or none");
  if (!overlays.empty() && overlays.size() != n) {
    return fail("give one --overlay per image, or none");
  }

  std::vector<rodfit::CentrelineResult> lines;
  for (size_t k = 0; k < n; ++k) {
    rodfit::CentrelineOptions options;
    if (!starts.empty()) {
      Eigen::Vector2d hint;
      if (!ParsePixel(starts[k], &hint)) return fail("--start '" + starts[k] + "' is not U,V");
      options.start_hint = hint;
    }
    lines.push_back(rodfit::ExtractCentrelineFromFile(images[k], cameras[k], options));
  }
  std::string csv;
  std::vector<std::vector<Eigen::Vector2d>> reprojected(n);
  if (n == 1) {
    csv = rodfit::FormatImagePointsCsv(lines[0].uv);
  } else {
    const std::vector<Eigen::Vector3d> points = rodfit::TriangulateCentrelines(
        cameras[0], lines[0].uv, cameras[1], lines[1].uv, images[0], images[1]);
    csv = rodfit::FormatPoints3dCsv(points);
    for (size_t k = 0; k < n; ++k) {
      for (const Eigen::Vector3d& p : points) {
        Eigen::Vector2d uv;
        if (rodfit::Project(cameras[k], p, &uv)) reprojected[k].push_back(uv);
      }
    }
  }
  // Overlays are encoded before anything is written, so a bad --overlay leaves no CSV behind.
  std::vector<std::string> encoded;
  for (size_t k = 0; k < overlays.size(); ++k) {
    encoded.push_back(rodfit::EncodeImage(
        overlays[k],
        rodfit::DrawOverlay(rodfit::ReadImageFile(images[k]), lines[k].uv, reprojected[k])));
  }
  // All outputs staged (one staging directory per output folder), then committed together,
  // the CSV's folder last: a failure on the way leaves every output location as it was, and no
  // CSV stands without its overlays.
  std::vector<std::pair<std::string, std::string>> files;  // path, contents; the CSV last
  for (size_t k = 0; k < overlays.size(); ++k) files.emplace_back(overlays[k], encoded[k]);
  files.emplace_back(output_path, csv);
  std::vector<std::pair<std::string, std::unique_ptr<rodfit::StagedDirectory>>> folders;
  std::vector<std::string> finals;
  rodfit::StagedDirectory* staged = nullptr;
  for (const auto& [path, contents] : files) {
    const std::filesystem::path file(path);
    const std::string folder =
        file.has_parent_path() ? file.parent_path().lexically_normal().string() : ".";
    staged = nullptr;
    for (const auto& [name, dir] : folders) {
      if (name == folder) staged = dir.get();
    }
    if (staged == nullptr) {
      folders.emplace_back(folder, std::make_unique<rodfit::StagedDirectory>(folder, true));
      staged = folders.back().second.get();
    }
    const std::string final_path = staged->FinalPath(file.filename().string());
    for (const std::string& other : finals) {
      if (other == final_path) return fail(path + " is given as two outputs");
    }
    finals.push_back(final_path);
    staged->Write(file.filename().string(), contents, "output file name");
  }
  std::vector<rodfit::StagedDirectory*> order;
  for (const auto& [name, dir] : folders) {
    if (dir.get() != staged) order.push_back(dir.get());
  }
  order.push_back(staged);  // the CSV's folder
  rodfit::CommitAll(order);
  for (size_t k = 0; k < n; ++k) std::cout << images[k] << ": " << lines[k].BriefReport() << "\n";
  return EXIT_SUCCESS;
}

struct Command {
  const char* name;
  const char* help;
  int (*run)(int argc, char** argv);
};

// Every command, in the order --help lists them (docs/cli.md has one section each).
const std::vector<Command>& Commands() {
  static const std::vector<Command> commands = {
      {"simulate", "solve every case of a scene; write DIR/shapes.csv", &RunSimulate},
      {"synth", "synthesize an experiment's observation files from its parameters", &RunSynth},
      {"extract", "image(s) of a thread -> centre-line pixels or triangulated points",
       &RunExtract},
      {"fit", "fit an experiment's parameters to its observations; write the profile JSON",
       &RunFit},
      {"rollout", "predict a recorded motion open-loop from its first frames; its error",
       &RunRollout},
      {"bench", "reference problems: error against time over settings; --stress", &RunBench},
      {"export", "a fitted profile for another simulator: sofa, xpbd or json", &RunExport},
  };
  return commands;
}

void PrintUsage(std::ostream& out) {
  out << "Usage: rodfit COMMAND [OPTIONS]   (rodfit COMMAND --help for its options)\n"
      << "       rodfit --version\n\n"
      << "Commands:\n";
  // Names padded to one column, so the descriptions line up.
  for (const Command& c : Commands()) {
    const std::string name = c.name;
    out << "  " << name << std::string(name.size() < 10 ? 10 - name.size() : 1, ' ') << c.help
        << "\n";
  }
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
  if (name == "--version") {
    std::cout << "rodfit " << RODFIT_VERSION << "\n";
    return EXIT_SUCCESS;
  }
  for (const Command& c : Commands()) {
    if (name != c.name) continue;
    try {
      return c.run(argc - 1, argv + 1);
    } catch (const std::bad_alloc&) {
      // Inputs within every documented limit can still ask for more memory than there is.
      std::cerr << "rodfit: out of memory while running " << c.name
                << " (inputs or limits too large for this machine)\n";
      return EXIT_FAILURE;
    } catch (const std::exception& e) {
      std::cerr << "rodfit: " << OneLine(e.what()) << "\n";
      return EXIT_FAILURE;
    }
  }
  std::cerr << "rodfit: unknown command '" << name << "' (see rodfit --help)\n";
  return EXIT_FAILURE;
}
