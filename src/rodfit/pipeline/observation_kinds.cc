// The registry of observation kinds (observation_kind.h). Compiled twice, as the kind files are:
// with RODFIT_ENTRY_FORMATS_ONLY it is the experiment reader's registry of entry formats (and
// LoadExperiment), without it the pipeline's registry of whole kinds.
#include <filesystem>
#include <stdexcept>

#include "rodfit/io/errors.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/observation_kind.h"
#include "rodfit/solve/integrator.h"

// The registration: one line per kind, the variable its file kinds/<name>.cc defines with
// RODFIT_OBSERVATION_KIND, in the order messages list the kinds.
#define RODFIT_OBSERVATION_KINDS(X) \
  X(kMarkers3d)                    \
  X(kPoints3d)                     \
  X(kImagePoints)                  \
  X(kImages)                       \
  X(kGraspForce)                   \
  X(kSurfacePoints)                \
  X(kReaction)                     \
  X(kRollMarkers)                  \
  X(kCriticalTwist)

namespace rodfit {

#ifdef RODFIT_ENTRY_FORMATS_ONLY

#define RODFIT_DECLARE_FORMAT(var) extern const EntryFormat var##Format;
RODFIT_OBSERVATION_KINDS(RODFIT_DECLARE_FORMAT)
#undef RODFIT_DECLARE_FORMAT

const std::vector<const EntryFormat*>& EntryFormats() {
#define RODFIT_FORMAT_ADDRESS(var) &var##Format,
  static const std::vector<const EntryFormat*> formats = {
      RODFIT_OBSERVATION_KINDS(RODFIT_FORMAT_ADDRESS)};
#undef RODFIT_FORMAT_ADDRESS
  return formats;
}

std::string EntryLabel(const ObservationSpec& spec) {
  // An entry whose value is in the experiment (a critical twist's value_deg) has no file.
  if (spec.file.empty()) return spec.type;
  return spec.type + " " + std::filesystem::path(spec.file).filename().string();
}

namespace {

class FormatRegistry final : public ObservationEntryKinds {
 public:
  std::vector<std::string> Names(bool moving) const override {
    std::vector<std::string> names;
    for (const EntryFormat* format : EntryFormats())
      if (!moving || format->may_move) names.push_back(format->name);
    return names;
  }
  void DeclareKeys(const std::string& type, EntryKeys* keys,
                   ObservationSpec* spec) const override {
    for (const EntryFormat* format : EntryFormats())
      if (type == format->name) return format->keys(keys, spec);
    throw std::invalid_argument("unknown observation type '" + type + "'");
  }
};

}  // namespace

const ObservationEntryKinds& ObservationEntryKindsOf() {
  static const FormatRegistry kinds;
  return kinds;
}

Experiment LoadExperiment(const std::string& path, bool parameters_optional) {
  return LoadExperiment(path, ObservationEntryKindsOf(), IntegratorNames(), parameters_optional);
}

Experiment ParseExperiment(const std::string& text, const std::string& path,
                           bool parameters_optional) {
  return ParseExperiment(text, path, ObservationEntryKindsOf(), IntegratorNames(),
                         parameters_optional);
}

#else  // the whole kinds

#define RODFIT_DECLARE_KIND(var) extern const ObservationKind var##Kind;
RODFIT_OBSERVATION_KINDS(RODFIT_DECLARE_KIND)
#undef RODFIT_DECLARE_KIND

const std::vector<const ObservationKind*>& ObservationKinds() {
#define RODFIT_KIND_ADDRESS(var) &var##Kind,
  static const std::vector<const ObservationKind*> kinds = {
      RODFIT_OBSERVATION_KINDS(RODFIT_KIND_ADDRESS)};
#undef RODFIT_KIND_ADDRESS
  return kinds;
}

const ObservationKind* FindObservationKind(const std::string& name) {
  for (const ObservationKind* kind : ObservationKinds())
    if (name == kind->name) return kind;
  return nullptr;
}

const ObservationKind& KindOf(const ObservationSpec& spec) {
  const ObservationKind* kind = FindObservationKind(spec.type);
  // The experiment reader admits no other type; a hand-made spec may hold anything.
  if (!kind) throw std::invalid_argument("unknown observation type '" + spec.type + "'");
  return *kind;
}

#endif

}  // namespace rodfit
