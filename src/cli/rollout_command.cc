// `rodfit rollout SCENE.yaml RECORDING.csv -o DIR`: open-loop prediction of a recorded motion
// (solve/rollout.h) and its mean absolute coordinate error.
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/recording.h"
#include "rodfit/solve/rollout.h"

int RunRollout(int argc, char** argv) {
  CLI::App app(
      "Predict a recorded motion open-loop: the rod of SCENE (its rod, parameters, gravity and "
      "dynamics) with a vertex at every marker of RECORDING, started from the first two frames, "
      "the held markers driven from the recording; write DIR/rollout.csv "
      "(frame,t,marker,s,held,observed_x,observed_y,observed_z,x,y,z) and print the mean "
      "absolute coordinate error.",
      "rodfit rollout");
  std::string scene_path, recording_path, output_dir, held_text = "0,1,-2,-1", initial = "equilibrium";
  double frame_rate = 0.0;
  app.add_option("scene", scene_path, "scene YAML with a dynamics: block (docs/formats.md)")->required();
  app.add_option("recording", recording_path, "markers CSV: frame,marker,x,y,z or t,marker,x,y,z")->required();
  app.add_option("-o,--output", output_dir, "output directory, created if missing")->required();
  app.add_option("--frame-rate", frame_rate, "[Hz] with a frame column")->check(CLI::Range(1e-6, 1e9));
  app.add_option("--held", held_text, "driven markers, comma separated; negative from the last (default 0,1,-2,-1)");
  app.add_option("--initial", initial, "equilibrium (default) or markers: the start shape")
      ->check(CLI::IsMember({"equilibrium", "markers"}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  const rodfit::Experiment experiment = rodfit::LoadExperiment(scene_path);
  if (!experiment.scene.dynamics)
    throw rodfit::InputError(scene_path, 1, "dynamics", "rollout needs a dynamics: block");
  const rodfit::MarkerRecording rec = rodfit::ReadMarkerRecording(recording_path, frame_rate);
  rodfit::RolloutOptions options;
  options.initial_equilibrium = initial == "equilibrium";
  options.held_markers.clear();
  {
    std::stringstream ss(held_text);
    std::string item;
    while (std::getline(ss, item, ',')) {
      double v = 0.0;
      if (!rodfit::ParseDouble(item, &v) || v != static_cast<int>(v))
        throw std::invalid_argument("--held: not an integer: '" + item.substr(0, 40) + "'");
      options.held_markers.push_back(static_cast<int>(v));
    }
  }
  rodfit::RolloutResult result;
  try {
    result = rodfit::Rollout(experiment.scene, rec.frame_interval, rec.frames, options,
                             experiment.statics);
  } catch (const std::invalid_argument& e) {
    throw rodfit::InputError(recording_path, 0, "", e.what());
  }
  std::string csv = "frame,t,marker,s,held,observed_x,observed_y,observed_z,x,y,z\n";
  for (size_t k = 0; k < result.predicted.size(); ++k) {
    for (int m = 0; m < static_cast<int>(result.marker_s.size()); ++m) {
      const Eigen::Vector3d o = rec.frames[k].col(m), p = result.predicted[k].col(m);
      auto num = [](double v) { return std::isfinite(v) ? rodfit::FormatDouble(v) : std::string(); };
      csv += std::to_string(k) + "," + rodfit::FormatDouble(k * rec.frame_interval) + "," +
             std::to_string(m) + "," + rodfit::FormatDouble(result.marker_s[m]) + "," +
             (result.held[m] ? "1," : "0,") + num(o[0]) + "," + num(o[1]) + "," + num(o[2]) + "," +
             num(p[0]) + "," + num(p[1]) + "," + num(p[2]) + "\n";
    }
  }
  if (!result.ok) {
    std::cerr << "rodfit rollout: " << result.reason << "\n";
    return EXIT_FAILURE;
  }
  rodfit::StagedDirectory out(output_dir);
  out.Write("rollout.csv", csv, "output file name");
  rodfit::RefuseOverwritingInput(out.FinalPath("rollout.csv"), rodfit::ExperimentInputs(experiment));
  out.Commit();
  char line[256];
  std::snprintf(line, sizeof(line),
                "mean absolute coordinate error: %.4g m over all markers, %.4g m over the "
                "predicted ones (%d samples, %zu frames)\n",
                result.mae_all, result.mae_predicted, result.samples, result.predicted.size());
  std::cout << line;
  return EXIT_SUCCESS;
}
