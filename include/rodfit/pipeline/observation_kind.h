// The observation kinds (docs/formats.md, "Observation entries"; docs/architecture.md): one
// registry row per kind, the `type` an experiment's observation entry names. Each kind declares,
// in one file of src/rodfit/pipeline/kinds/, everything about it: the keys its entries take (the
// experiment reader's checks), whether it may be observed over time, how its files become
// measurements of the fit (rodfit/fit/measurement.h) statically and per frame, how synth writes
// its files, and how the fit report shows it. A new kind is that file plus its line in
// observation_kinds.cc (RODFIT_OBSERVATION_KINDS).
#pragma once

#include <string>
#include <vector>

#include "rodfit/fit/fit.h"
#include "rodfit/fit/motion_fit.h"
#include "rodfit/io/experiment.h"

namespace rodfit {

class KindContext;  // pipeline/kind_support.h: what a builder reads
struct SynthEntry;  // synth/synth_entry.h: what a synth generator reads

/// How the fit report shows an entry of a kind (report/fit_report_page.cc).
enum class ReportView {
  kMarkers3d,  ///< 3-D markers at s: the shape views, observed and fitted positions
  kPoints3d,   ///< unordered 3-D centre-line samples: the shape views
  kPixels,     ///< pixels of one camera, with or without s: the camera view
  kImage,      ///< a camera image, reduced to pixels: the camera view over the image
  kHapticLog,  ///< a haptic log: force against time, and the force residuals
  kReaction,   ///< readings of a held point's reaction: the force residuals (over time)
  kSurface,    ///< points around a poke: the section view
  kValue,      ///< a value of the case (a critical twist): the misfit table only
};

/// What the experiment reader knows of a kind: its entry's format.
struct EntryFormat {
  const char* name;     ///< the entries' `type`
  const char* summary;  ///< one line for the docs: what is measured, the file's columns
  /// Declares the keys an entry takes (EntryKeys; static or moving scene) into `spec`.
  void (*keys)(EntryKeys* keys, ObservationSpec* spec);
  /// Whether an entry may be observed over time (a sequence in a scene with a dynamics: block).
  bool may_move;
};

/// One observation kind: its entry's format and what it does. Every member is set (a kind that
/// may not move leaves the sequence functions null); the struct is a literal type, so the
/// registry is built before any code runs.
struct ObservationKind : EntryFormat {
  /// Reads the entry's files into measurements of the static case `fit_case`; a kind whose
  /// readings each hold the rod differently (a haptic log's quasi-static samples) appends cases
  /// of their own to `more_cases`. Throws InputError naming the file, line and column.
  void (*build)(const KindContext& context, FitCase* fit_case, std::vector<FitCase>* more_cases);
  /// Reads the entry's file as a sequence of a moving case (null unless may_move).
  ObservationSequence (*build_sequence)(const KindContext& context);
  /// The contents of the entry's file synthesized from the solved case (synth); `report` gets a
  /// line of what was written.
  std::string (*synthesize)(const SynthEntry& entry, std::string* report);
  /// The same for a moving case, from its run (null unless may_move).
  std::string (*synthesize_sequence)(const SynthEntry& entry, std::string* report);
  ReportView view;
};

/// Defines a kind at the end of its file, kinds/<name>.cc:
///   RODFIT_OBSERVATION_KIND(kName, (EntryFormat{name, summary, Keys, may_move}),
///                           Build, BuildSequence, Synthesize, SynthesizeSequence, view);
/// Each kind file is compiled twice (CMakeLists.txt): whole into the pipeline, and with
/// RODFIT_ENTRY_FORMATS_ONLY into the experiment reader's library, which the `rodfit` executable
/// links without Ceres and OpenCV (docs/cli.md, "Start-up"): that build keeps the entry format
/// alone, and the file puts what it does inside #ifndef RODFIT_ENTRY_FORMATS_ONLY.
#ifdef RODFIT_ENTRY_FORMATS_ONLY
#define RODFIT_OBSERVATION_KIND(var, format, ...) extern const EntryFormat var##Format = format
#else
#define RODFIT_OBSERVATION_KIND(var, format, ...) \
  extern const ObservationKind var##Kind = {format, __VA_ARGS__}
#endif

/// Every kind's entry format, in the order messages list them (the experiment reader's registry,
/// in the light library).
const std::vector<const EntryFormat*>& EntryFormats();

/// The registry as the experiment reader sees it (io/experiment.h).
const ObservationEntryKinds& ObservationEntryKindsOf();

/// The label of an entry in tables and messages: "TYPE FILE" (the file's name).
std::string EntryLabel(const ObservationSpec& spec);

/// Every kind, in the order messages list them.
const std::vector<const ObservationKind*>& ObservationKinds();

/// The kind named `name`, or null.
const ObservationKind* FindObservationKind(const std::string& name);

/// The kind of an entry read by LoadExperiment (whose type is always a kind's name).
const ObservationKind& KindOf(const ObservationSpec& spec);

}  // namespace rodfit
