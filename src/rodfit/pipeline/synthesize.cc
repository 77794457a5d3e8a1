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

// The bundle's output paths, each claimed by the one who writes it: no two the same.
class OutputClaims {
 public:
  explicit OutputClaims(const Experiment& ex) : ex_(ex) {
    owner_[kSynthExperimentFile] = "the re-emitted experiment";
    owner_[kSynthTruthFile] = "the truth";
  }
  // `rel` (relative to the output folder) for `who`; an InputError at `line`, `key` when it
  // names a folder or another writes it.
  void Claim(const std::string& rel, const std::string& who, int line, const std::string& key) {
    // A folder (`.`, `..`, `dir/`) names no file to write.
    const std::string name = fs::path(rel).filename().string();
    if (name.empty() || name == "." || name == "..")
      throw InputError(ex_.path, line, key, "names a folder, not a file to write");
    const auto [it, inserted] = owner_.emplace(rel, who);
    if (!inserted && it->second != who) {
      throw InputError(ex_.path, line, key, "writes " + rel + ", which " + it->second + " writes");
    }
  }
  std::string Relative(const std::string& p) const { return SynthRelativePath(p, ex_.directory); }

 private:
  const Experiment& ex_;
  std::map<std::string, std::string> owner_;  // relative output path -> who writes it
};

// The cases' solutions, and their shapes as the bundle's truth. A moving scene's truth shapes
// are its cases' initial equilibria (held points where their paths start); its observations
// are sequences along the runs (the kinds' sequence generators).
std::vector<CaseSolution> SolveTruth(const Experiment& ex, const SynthOptions& options,
                                     SynthBundle* bundle) {
  Experiment at_start;
  if (ex.scene.dynamics) {
    at_start = ex;
    at_start.scene.dynamics.reset();
    for (LoadCase& c : at_start.scene.cases) c = CaseAtStart(c);
  }
  std::vector<CaseSolution> solutions =
      SolveCases(ex.scene.dynamics ? at_start : ex, options.statics);
  for (size_t c = 0; c < solutions.size(); ++c)
    bundle->truth.push_back({ex.scene.cases[c].name, solutions[c].shape_s, solutions[c].shape});
  return solutions;
}

// Claims each entry's file, then loads each camera once (by CameraKey: path, and index in a
// stereo file) and claims its file; `camera_order`: the camera files in order of first use.
void ClaimEntries(const Experiment& ex, OutputClaims* claims, std::map<std::string, Camera>* cameras,
                  std::vector<std::string>* camera_order) {
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
      claims->Claim(claims->Relative(spec.file), key, spec.line, key + ".file");
    }
  }
  for (size_t c = 0; c < ex.cases.size(); ++c) {
    for (size_t o = 0; o < ex.cases[c].observations.size(); ++o) {
      const ObservationSpec& spec = ex.cases[c].observations[o];
      if (spec.camera.empty() || cameras->count(CameraKey(spec))) continue;
      const std::string key = EntryKey(static_cast<int>(c), static_cast<int>(o)) + ".camera";
      try {
        (*cameras)[CameraKey(spec)] = LoadObservationCamera(spec);
      } catch (const CameraFileError& e) {
        throw InputError(ex.path, spec.line, key, e.what());
      }
      // The file is copied once (both cameras of a stereo file come from one file).
      if (std::find(camera_order->begin(), camera_order->end(), spec.camera) == camera_order->end())
        camera_order->push_back(spec.camera);
      claims->Claim(claims->Relative(spec.camera), "camera " + spec.camera, spec.line, key);
    }
  }
}

// Each entry's file as its kind synthesizes it, with its report line.
void SynthesizeEntries(const Experiment& ex, const SynthOptions& options,
                       const std::vector<CaseSolution>& solutions,
                       const std::map<std::string, Camera>& cameras, const OutputClaims& claims,
                       SynthBundle* bundle) {
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
      const std::string file = claims.Relative(spec.file);
      Random random(options.seed, file);
      SynthEntry entry{&ex,
                       &options,
                       &bundle->truth[c],
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
      bundle->files.emplace_back(file, std::move(contents));
      bundle->report.push_back(report);
    }
  }
}

// The inputs copied beside the observations, so that DIR/experiment.yaml is self-contained: the
// camera files, the masks and the start shapes.
void CopyInputs(const Experiment& ex, const std::vector<std::string>& camera_order,
                OutputClaims* claims, SynthBundle* bundle) {
  for (const std::string& camera : camera_order) {
    bundle->files.emplace_back(claims->Relative(camera), ReadBytes(camera, "the camera file"));
  }
  std::set<std::string> masks;
  for (size_t c = 0; c < ex.cases.size(); ++c) {
    for (size_t o = 0; o < ex.cases[c].observations.size(); ++o) {
      const ObservationSpec& spec = ex.cases[c].observations[o];
      if (spec.mask.empty() || !masks.insert(spec.mask).second) continue;
      const std::string key = EntryKey(static_cast<int>(c), static_cast<int>(o)) + ".mask";
      claims->Claim(claims->Relative(spec.mask), "mask " + spec.mask, spec.line, key);
      bundle->files.emplace_back(claims->Relative(spec.mask), ReadBytes(spec.mask, "the mask"));
    }
  }
  std::set<std::string> starts;
  for (size_t c = 0; c < ex.scene.cases.size(); ++c) {
    const StartShape& start = ex.scene.cases[c].start;
    if (start.kind != StartShape::Kind::kPoints || !starts.insert(start.file).second) continue;
    const std::string key = "cases[" + std::to_string(c) + "].start";
    claims->Claim(claims->Relative(start.file), "start shape " + start.file, ex.cases[c].line, key);
    bundle->files.emplace_back(claims->Relative(start.file),
                               ReadBytes(start.file, "the start shape"));
  }
}

}  // namespace

SynthBundle MakeSynthBundle(const Experiment& experiment, const SynthOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("SynthOptions: " + why);
  const Experiment& ex = experiment;
  SynthBundle bundle;
  const std::vector<CaseSolution> solutions = SolveTruth(ex, options, &bundle);
  // Output paths first: each entry's file and each camera once, with no two the same.
  OutputClaims claims(ex);
  std::map<std::string, Camera> cameras;
  std::vector<std::string> camera_order;
  ClaimEntries(ex, &claims, &cameras, &camera_order);
  SynthesizeEntries(ex, options, solutions, cameras, claims, &bundle);
  CopyInputs(ex, camera_order, &claims, &bundle);
  const auto rel = [&claims](const std::string& p) { return claims.Relative(p); };
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
