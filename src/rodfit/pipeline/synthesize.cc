// The synth driver (synthesize.h): solve, then every entry's generator by its kind, then the
// copied inputs, the re-emitted experiment and the truth, all in memory.
#include "rodfit/pipeline/synthesize.h"

#include <algorithm>
#include <filesystem>
#include <map>
#include <set>
#include <stdexcept>

#include "rodfit/fit/motion_fit.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/pipeline/image_files.h"
#include "rodfit/pipeline/observation_kind.h"
#include "rodfit/solve/case_dynamics.h"
#include "rodfit/synth/synth_entry.h"
#include "rodfit/vision/camera_file.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;

std::string EntryKey(int c, int o) {
  return "cases[" + std::to_string(c) + "].observations[" + std::to_string(o) + "]";
}

std::string ReadBytes(const std::string& path, const std::string& what) {
  return ReadInputFile(path, what);
}

}  // namespace

SynthBundle MakeSynthBundle(const Experiment& experiment, const SynthOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("SynthOptions: " + why);
  const Experiment& ex = experiment;
  SynthBundle bundle;
  // A moving scene's truth shapes are its cases' initial equilibria (held points where their
  // paths start); its observations are sequences along the runs (the kinds' sequence
  // generators).
  Experiment at_start;
  if (ex.scene.dynamics) {
    at_start = ex;
    at_start.scene.dynamics.reset();
    for (LoadCase& c : at_start.scene.cases) c = CaseAtStart(c);
  }
  const std::vector<CaseSolution> solutions =
      SolveCases(ex.scene.dynamics ? at_start : ex, options.statics);
  for (size_t c = 0; c < solutions.size(); ++c)
    bundle.truth.push_back({ex.scene.cases[c].name, solutions[c].shape_s, solutions[c].shape});

  // Output paths first: each entry's file and each camera once, with no two the same.
  std::map<std::string, std::string> owner;  // relative output path -> who writes it
  owner[kSynthExperimentFile] = "the re-emitted experiment";
  owner[kSynthTruthFile] = "the truth";
  auto claim = [&](const std::string& rel, const std::string& who, int line,
                   const std::string& key) {
    // A folder (`.`, `..`, `dir/`) names no file to write.
    const std::string name = fs::path(rel).filename().string();
    if (name.empty() || name == "." || name == "..")
      throw InputError(ex.path, line, key, "names a folder, not a file to write");
    const auto [it, inserted] = owner.emplace(rel, who);
    if (!inserted && it->second != who) {
      throw InputError(ex.path, line, key, "writes " + rel + ", which " + it->second + " writes");
    }
  };
  const auto rel = [&](const std::string& p) { return SynthRelativePath(p, ex.directory); };
  std::map<std::string, Camera> cameras;  // by CameraKey (path, and index in a stereo file)
  std::vector<std::string> camera_order;  // first use
  for (size_t c = 0; c < ex.cases.size(); ++c) {
    for (size_t o = 0; o < ex.cases[c].observations.size(); ++o) {
      const ObservationSpec& spec = ex.cases[c].observations[o];
      const std::string key = EntryKey(static_cast<int>(c), static_cast<int>(o));
      // An entry whose value the experiment holds (a critical twist's value_deg) has nowhere to
      // put what synth would measure.
      if (spec.file.empty())
        throw InputError(ex.path, spec.line, key,
                         "synth writes each observation to its file: give this " + spec.type +
                             " entry a `file:` instead of its value");
      claim(rel(spec.file), key, spec.line, key + ".file");
    }
  }
  for (size_t c = 0; c < ex.cases.size(); ++c) {
    for (size_t o = 0; o < ex.cases[c].observations.size(); ++o) {
      const ObservationSpec& spec = ex.cases[c].observations[o];
      if (spec.camera.empty() || cameras.count(CameraKey(spec))) continue;
      const std::string key = EntryKey(static_cast<int>(c), static_cast<int>(o)) + ".camera";
      try {
        cameras[CameraKey(spec)] = LoadObservationCamera(spec);
      } catch (const CameraFileError& e) {
        throw InputError(ex.path, spec.line, key, e.what());
      }
      // The file is copied once (both cameras of a stereo file come from one file).
      if (std::find(camera_order.begin(), camera_order.end(), spec.camera) == camera_order.end())
        camera_order.push_back(spec.camera);
      claim(rel(spec.camera), "camera " + spec.camera, spec.line, key);
    }
  }

  for (size_t c = 0; c < ex.cases.size(); ++c) {
    // A moving case's shape at each time is its whole rod's, at these arc lengths.
    std::vector<double> arc;
    if (ex.scene.dynamics && !ex.cases[c].observations.empty()) {
      try {
        arc = CaseVertexArcLengths(ex.scene, static_cast<int>(c));
      } catch (const std::invalid_argument& e) {
        // Named as the entry's run would name it (its model is the same).
        throw InputError(ex.path, ex.cases[c].observations[0].line,
                         EntryKey(static_cast<int>(c), 0),
                         "case '" + ex.scene.cases[c].name + "': " + e.what());
      }
    }
    for (size_t o = 0; o < ex.cases[c].observations.size(); ++o) {
      const ObservationSpec& spec = ex.cases[c].observations[o];
      const std::string file = rel(spec.file);
      Random random(options.seed, file);
      SynthEntry entry{&ex,
                       &options,
                       &bundle.truth[c],
                       &solutions[c],
                       &spec,
                       spec.camera.empty() ? nullptr : &cameras.at(CameraKey(spec)),
                       EntryKey(static_cast<int>(c), static_cast<int>(o)),
                       spec.camera,
                       &random,
                       static_cast<int>(c),
                       "",
                       file,
                       arc};
      const ObservationKind& kind = KindOf(spec);
      std::string report;
      std::string contents = ex.scene.dynamics ? kind.synthesize_sequence(entry, &report)
                                               : kind.synthesize(entry, &report);
      bundle.files.emplace_back(file, std::move(contents));
      bundle.report.push_back(report);
    }
  }
  for (const std::string& camera : camera_order) {
    bundle.files.emplace_back(rel(camera), ReadBytes(camera, "the camera file"));
  }
  // Masks and start shapes are copied too, so DIR/experiment.yaml is self-contained.
  std::set<std::string> masks;
  for (size_t c = 0; c < ex.cases.size(); ++c) {
    for (size_t o = 0; o < ex.cases[c].observations.size(); ++o) {
      const ObservationSpec& spec = ex.cases[c].observations[o];
      if (spec.mask.empty() || !masks.insert(spec.mask).second) continue;
      const std::string key = EntryKey(static_cast<int>(c), static_cast<int>(o)) + ".mask";
      claim(rel(spec.mask), "mask " + spec.mask, spec.line, key);
      bundle.files.emplace_back(rel(spec.mask), ReadBytes(spec.mask, "the mask"));
    }
  }
  std::set<std::string> starts;
  for (size_t c = 0; c < ex.scene.cases.size(); ++c) {
    const StartShape& start = ex.scene.cases[c].start;
    if (start.kind != StartShape::Kind::kPoints || !starts.insert(start.file).second) continue;
    const std::string key = "cases[" + std::to_string(c) + "].start";
    claim(rel(start.file), "start shape " + start.file, ex.cases[c].line, key);
    bundle.files.emplace_back(rel(start.file), ReadBytes(start.file, "the start shape"));
  }
  bundle.files.emplace_back(kSynthExperimentFile,
                            EmitExperimentYaml(ReadBytes(ex.path, "the experiment"), ex, rel));
  bundle.files.emplace_back(kSynthTruthFile, FormatTruthJson(ex, bundle.truth, options.seed));
  return bundle;
}

SynthBundle Synthesize(const Experiment& experiment, const std::string& output_dir,
                       const SynthOptions& options) {
  SynthBundle bundle = MakeSynthBundle(experiment, options);
  // Observation files are synth's outputs; the experiment, cameras and start shapes its inputs.
  WriteSynthBundle(bundle, output_dir, experiment.path,
                   ExperimentInputs(experiment, /*with_data_files=*/false));
  return bundle;
}

}  // namespace rodfit
