// The experiment / scene YAML (docs/formats.md), read into a Scene (what model/ and solve/ need)
// plus what identification needs on top: per-parameter fit settings, per-case observation specs
// and the optional `fit:` block. Everything is validated here, so a mistake in the file is an
// InputError naming the file, the 1-based line and the key (e.g. `cases[1].clamp.normal`),
// never a failure deep inside a solve.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "rodfit/fit/fit.h"
#include "rodfit/io/settings.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/model/scene.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

/// Limits of an experiment / scene YAML (docs/formats.md, "Limits"), each checked before the
/// work it bounds, with a message that gives it. The text is bounded before yaml-cpp parses it.
inline constexpr std::uintmax_t kMaxYamlBytes = std::uintmax_t{4} << 20;  ///< 4 MiB
inline constexpr int kMaxYamlNesting = 64;     ///< levels (flow and block); a scene needs 6
/// YAML nodes with aliases expanded: 2000 aliases of a large case are 2000 cases.
inline constexpr int kMaxYamlNodes = 1000000;
inline constexpr int kMaxCases = 1000;         ///< cases in a file
inline constexpr int kMaxSegments = 100000;    ///< rod.segments (about 1 s per solve there)
inline constexpr int kMaxSectionNodes = 256;   ///< section.nodes (the ring's solve is dense)
inline constexpr int kMaxSamples = 100000;     ///< an observation's count (synth's samples)
inline constexpr int kMaxDragSteps = 1000;     ///< grasp_force count (cases of the fit)
inline constexpr double kMaxBlurPx = 100.0;    ///< images: blur [px]
inline constexpr double kMaxNoiseGrey = 255.0; ///< images: noise [grey levels]

/// One entry of a case's `observations:` (docs/formats.md, "Observation entries"). Which keys an
/// entry takes is declared by its kind (rodfit/pipeline/observation_kind.h, through EntryKeys
/// below); this struct holds every key any kind reads.
struct ObservationSpec {
  std::string type;       ///< the observation kind (ObservationKinds())
  std::string file;       ///< data file (CSV or image), resolved against the YAML's folder
  std::string camera;     ///< camera file, resolved likewise; empty for 3-D types
  /// Which camera of a stereo calibration file `camera` is (1 or 2; docs/formats.md, "Camera
  /// files"); 0: the file holds one camera.
  int camera_index = 0;
  double sigma = 0.0;     ///< measurement standard deviation, > 0
  std::vector<double> s;  ///< [m] arc lengths of the markers to synthesize, in [0, L]
  int count = 0;          ///< number of markers / points to synthesize (0 = not given)
  double outliers = 0.0;  ///< fraction of synthesized samples made outliers, in [0, 1)
  /// grasp_force: tool speed [m/s] below which a haptic sample counts as quasi-static.
  double max_speed = 1e-3;
  double blur = 0.0;      ///< [px] `images`: Gaussian blur sigma of synthesized images, >= 0
  double noise = 0.0;     ///< [grey levels] `images`: pixel noise sigma of synthesized images
  /// [px] `images`: the extraction's region of interest, corners x0, y0 (inclusive) and x1, y1
  /// (exclusive), 0 <= x0 < x1, 0 <= y0 < y1 (CentrelineOptions::roi).
  std::optional<std::array<int, 4>> roi;
  /// `images`: a mask image (non-zero = may hold thread; CentrelineOptions::mask), resolved
  /// against the YAML's folder; empty = none.
  std::string mask;
  /// [Hz] a sequence's frames (an entry of a moving scene): reading, the rate of a `frame`
  /// column; synth, the sampling rate (0: not given; synth then samples every written frame of
  /// the dynamics).
  double frame_rate = 0.0;
  double drop = 0.0;      ///< a sequence: fraction of samples synth leaves missing, [0, 1)
  std::string point;      ///< `reaction`: the held point (HeldReaction::point)
  double sigma_moment = 0.0;  ///< [N m] `reaction`: moment sigma; 0: no moment
  /// grasp_force: how the device logged. A row's tool position p and force f, in the device's
  /// frame and units, become the scene's p_scene = R (position_scale p) + t and
  /// f_scene = force_sign R (force_scale f): `unit` (m | mm), `force_unit` (N | mN),
  /// `device_frame: {rotation, translation}` and `force_on` (instrument: +1 | tissue: -1).
  double position_scale = 1.0;                             ///< [m per file unit]
  double force_scale = 1.0;                                ///< [N per file unit]
  Eigen::Matrix3d device_rotation = Eigen::Matrix3d::Identity();  ///< R: device to scene axes
  Vec3 device_translation = Vec3::Zero();                  ///< t [m]: device origin in the scene
  double force_sign = 1.0;  ///< +1: the log holds the force on the instrument; -1: on the tissue
  /// The numeric keys of a kind that no other kind reads, by key (roll_markers' sigma_roll).
  std::map<std::string, double> kind_values;
  int line = 0;           ///< 1-based line of the entry
};

/// The keys of one observation entry, declared once per observation kind: the kind's `keys`
/// function (rodfit/pipeline/observation_kind.h) calls these for every key its entries take, in
/// the order messages list them, and the experiment reader implements them over the entry's
/// YAML mapping, each with its check and an InputError naming the file, line and key. A key the
/// kind does not declare is an error ("not allowed for type ..."), as is a required key missing.
class EntryKeys {
 public:
  virtual ~EntryKeys() = default;
  /// The entry is read in a moving scene (a dynamics: block): it is a sequence over time.
  virtual bool moving() const = 0;
  /// The case the entry belongs to (its poke, its held points) and the rod.
  virtual const LoadCase& load_case() const = 0;
  virtual const RodSpec& rod() const = 0;

  /// A file path, relative to the YAML file's folder.
  virtual void Path(const char* key, std::string* path, bool required) = 0;
  /// A number > 0.
  virtual void Positive(const char* key, double* value, bool required) = 0;
  /// A number in [lo, hi].
  virtual void Number(const char* key, double* value, double lo, double hi) = 0;
  /// A fraction in [0, 1).
  virtual void Fraction(const char* key, double* value) = 0;
  /// An integer in [lo, hi].
  virtual void Integer(const char* key, int* value, int lo, int hi) = 0;
  /// A non-empty list of arc lengths [m] in [0, L].
  virtual void ArcLengths(const char* key, std::vector<double>* s) = 0;
  /// One arc length [m] in [0, L] away from the clamp (a grasped point), appended to *s.
  virtual void GraspArcLength(const char* key, std::vector<double>* s) = 0;
  /// [x0, y0, x1, y1] pixel corners (x1, y1 exclusive).
  virtual void Roi(const char* key, std::optional<std::array<int, 4>>* roi) = 0;
  /// One word of `choices`, setting *value to its number; otherwise `expected` (e.g. "must be
  /// m or mm") and what was given.
  virtual void Choice(const char* key, double* value,
                      const std::vector<std::pair<std::string, double>>& choices,
                      const std::string& expected) = 0;
  /// {rotation: 3 rows of 3, translation: [x, y, z]}: a proper rotation and a shift [m].
  virtual void Frame(const char* key, Eigen::Matrix3d* rotation, Vec3* translation) = 0;
  /// One of the case's held points: clamp, end_clamp, end_pin, pins[k] or grasp.
  virtual void HeldPoint(const char* key, std::string* point, bool required) = 0;
  /// At most one of the two keys.
  virtual void Exclusive(const char* key, const char* other) = 0;
  /// Unless `ok`: an error at `key` (at the entry when it does not hold the key).
  virtual void Check(bool ok, const char* key, const std::string& message) = 0;
};

/// The observation kinds the reader knows (rodfit/pipeline/observation_kind.h implements this
/// with its registry): their names and the keys each declares.
class ObservationEntryKinds {
 public:
  virtual ~ObservationEntryKinds() = default;
  /// Every kind's name, or those that may be observed over time (`moving`), in order.
  virtual std::vector<std::string> Names(bool moving) const = 0;
  /// Declares the keys of an entry of kind `type` (one of Names(false)) on `keys`, reading
  /// them into `spec` when `keys` reads.
  virtual void DeclareKeys(const std::string& type, EntryKeys* keys,
                           ObservationSpec* spec) const = 0;
};

/// The camera an image entry names, as a key and a label: its file, with "[1]" or "[2]" for a
/// camera of a stereo file.
std::string CameraKey(const ObservationSpec& spec);

/// A case beyond its physics (which is Scene::cases at the same index).
struct CaseSpec {
  std::vector<ObservationSpec> observations;
  int line = 0;  ///< 1-based line of the case's entry
};

/// The optional top-level `fit:` block: FitOptions' settings as the file gives them (their
/// defaults where it does not; rodfit/io/settings.h declares the keys).
struct FitSpec : FitOptions {
  int line = 0;  ///< 1-based line of `fit:`, 0 when absent
};

struct Experiment {
  std::string path;       ///< the YAML file as given
  std::string directory;  ///< its folder; relative paths inside the file are resolved here
  Scene scene;            ///< rod, material (the parameters' values), gravity, cases
  /// The `parameters:` block, keyed by name: only the names present in the file (rows of the
  /// parameter table, rodfit/model/material_parameters.h, and the spring zones' own). Each
  /// value is in the parameter's SI unit; a fitted value and its bounds are > 0 (fitted in log
  /// space, docs/solvers.md, "The fit"), min < max, min <= value <= max.
  std::map<std::string, Parameter> parameters;
  std::vector<CaseSpec> cases;  ///< parallel to scene.cases
  FitSpec fit;
  /// 1-based line of `dynamics.integrator` (of `dynamics:` when the key is absent), 0 without a
  /// dynamics: block: where a fit that cannot use the integrator points.
  int integrator_line = 0;
  /// The optional top-level `solver:` block (max_iterations, gradient_tolerance,
  /// step_tolerance, escape_saddles); defaults otherwise.
  StaticsOptions statics;
};

/// Reads and validates an experiment / scene YAML, its observation entries by `kinds` and its
/// `dynamics.integrator` by `integrators` (the registered schemes' names, IntegratorNames() of
/// rodfit/solve/integrator.h): what rodfit/pipeline/experiment.h's LoadExperiment does with the
/// registries (see there; io links neither). Throws InputError (rodfit/io/errors.h).
Experiment LoadExperiment(const std::string& path, const ObservationEntryKinds& kinds,
                          const std::vector<std::string>& integrators,
                          bool parameters_optional = false);

/// The file text variant; `path` names the file in messages and anchors relative paths.
Experiment ParseExperiment(const std::string& text, const std::string& path,
                           const ObservationEntryKinds& kinds,
                           const std::vector<std::string>& integrators,
                           bool parameters_optional = false);

}  // namespace rodfit
