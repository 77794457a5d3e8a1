// `rodfit synth EXPERIMENT.yaml -o DIR [--seed N] [--noise-free]`: every observation file of an
// experiment synthesized from its parameter values (docs/cli.md, "synth"). In the commands module:
// rendering images links OpenCV.
#include <cstdint>
#include <cstdlib>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/io/experiment.h"
#include "rodfit/synth/synth.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/synthesize.h"

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
