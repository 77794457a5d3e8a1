// What the observation kinds' files (pipeline/kinds/) share: the context a builder reads (the
// experiment, the case, the entry, the case's vertices, the cameras), the checks of observed
// values against the rod and the camera, and the label of an entry. Internal to the pipeline.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/io/csv.h"
#include "rodfit/io/experiment.h"
#include "rodfit/observe/camera.h"
#include "rodfit/pipeline/observation_kind.h"

namespace rodfit {

/// Cameras by CameraKey, each file read once per assembly.
class CameraCache {
 public:
  /// The entry's camera (LoadObservationCamera). Throws CameraFileError.
  const Camera& Get(const ObservationSpec& spec);

 private:
  std::map<std::string, Camera> cameras_;
};

/// What a kind's builder reads.
class KindContext {
 public:
  KindContext(const Experiment& experiment, int case_index, const ObservationSpec& spec,
              const LoadCase& load_case, const std::vector<double>& vertex_arc_length,
              CameraCache* cameras)
      : experiment_(experiment), case_index_(case_index), spec_(spec), load_case_(load_case),
        arc_(vertex_arc_length), cameras_(cameras) {}

  const Experiment& experiment() const { return experiment_; }
  int case_index() const { return case_index_; }
  const ObservationSpec& spec() const { return spec_; }
  /// The case as the fit solves it (a symmetric case whole).
  const LoadCase& load_case() const { return load_case_; }
  /// Rest arc lengths of the case's vertices [m] (held points on the vertex nearest them).
  const std::vector<double>& vertex_arc_length() const { return arc_; }
  int num_vertices() const { return static_cast<int>(arc_.size()); }
  double rod_length() const { return experiment_.scene.rod.length; }
  /// The entry's camera (image kinds), read once per file.
  const Camera& camera() const { return cameras_->Get(spec_); }
  /// "TYPE FILE": the entry in tables and messages (EntryLabel).
  std::string label() const { return EntryLabel(spec_); }

 private:
  const Experiment& experiment_;
  int case_index_;
  const ObservationSpec& spec_;
  const LoadCase& load_case_;
  const std::vector<double>& arc_;
  CameraCache* cameras_;
};

/// A 3-D point more than this many rod lengths from the case's clamp cannot lie on the rod, even
/// as an outlier within its reach: a unit or frame mistake, or a value such as 1e308. Points
/// beyond kAbsurdReachLengths are refused first, by their line (millimetres given as metres lie
/// about 1000 lengths out and are told as such by CheckSpread).
inline constexpr double kMaxReachLengths = 100.0;
inline constexpr double kAbsurdReachLengths = 1e4;

/// Throws InputError at the row's line and `column` when p lies farther than `lengths` rod
/// lengths from the clamp.
void CheckReach(const CsvTable& t, int row, const Eigen::Vector3d& p, const Vec3& clamp,
                double length, const char* column = "x", double lengths = kMaxReachLengths);

/// Throws InputError at the row's line and column s unless s lies in [0, L] (up to round-off).
void CheckArcLength(const CsvTable& t, int row, double s, double length);

/// 3-D observations are in metres. Points spread (bounding-box diagonal) over more than 100 rod
/// lengths cannot all lie on the rod, even with outliers inside the rod's reach: almost always
/// millimetres written as metres (a spread of ~1000 lengths), caught here rather than as a fit
/// that fails or converges to nonsense. `what` names them ("the markers").
void CheckSpread(const std::string& file, const std::string& what,
                 const std::vector<Eigen::Vector3d>& points, double length);

/// The three checks in the order a user is best served by: an absurd point by its line, then
/// millimetres as metres (the likelier mistake), then any single point too far.
void CheckPointsOnRod(const CsvTable& t, const std::string& what,
                      const std::vector<Eigen::Vector3d>& points, const Vec3& clamp,
                      double length);

/// An observed pixel must lie on its camera's sensor, give or take a quarter of the image (noise
/// added to samples near the border, refinement at the border): one farther out is not a pixel
/// of that camera (another camera's file, a value such as 1e308). Throws InputError naming the
/// row's line, the column u and the camera file.
void CheckOnSensor(const CsvTable& t, int row, const Eigen::Vector2d& uv, const Camera& camera,
                   const std::string& camera_file);

/// Numbers in messages, as a person would type them.
std::string Short(double v);

}  // namespace rodfit
