// shapes.csv, the output of `rodfit simulate` (docs/formats.md, "CSV files"): one row per vertex of
// every case, columns `case,vertex,s,x,y,z`, numbers at full precision so the file round-trips
// exactly. Plain data in, so io/ needs no solver; the CLI fills CaseShape from a RodModel and
// RodState.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace rodfit {

/// The equilibrium centre-line of one case.
struct CaseShape {
  std::string name;       ///< case name (no commas, quotes or line breaks)
  std::vector<double> s;  ///< [m] rest arc length of each vertex
  Eigen::Matrix3Xd x;     ///< [m] vertex positions, column i; as many columns as s has entries
};

/// The whole file's text, header included.
std::string FormatShapesCsv(const std::vector<CaseShape>& shapes);

/// `case,point,s,x,y,z,fx,fy,fz,mx,my,mz`: the force [N] and moment [N m] (about the held point
/// x,y,z [m]) the rod exerts on each holder, one row per held point of every case: the clamp,
/// an end clamp or end pin, pins, a grasp (the force on the instrument). The moment is zero for
/// points held in position only.
struct CaseForce {
  std::string name;
  std::string point;  ///< clamp, end_clamp, end_pin, pins[k], grasp
  double s = 0.0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
};
std::string FormatForcesCsv(const std::vector<CaseForce>& forces);
void WriteForcesCsv(const std::string& path, const std::vector<CaseForce>& forces);

/// `case,converged,stable,iterations,gradient_norm,reason`: how each case's solve ended
/// (gradient_norm [N]; reason in double quotes). `seconds` is not written: outputs hold no wall
/// time, so a run repeated gives the same bytes.
struct CaseSummaryRow {
  std::string name;
  bool converged = false, stable = false;
  int iterations = 0;
  double gradient_norm = 0.0, seconds = 0.0;
  std::string reason;
};
std::string FormatSummaryCsv(const std::vector<CaseSummaryRow>& rows);

/// `case,node,x0,y0,z0,x,y,z`: a poked case's cross-section ring, rest and deformed [m].
struct CaseSection {
  std::string name;
  Eigen::Matrix3Xd rest, deformed;
};
std::string FormatSectionsCsv(const std::vector<CaseSection>& sections);
void WriteSectionsCsv(const std::string& path, const std::vector<CaseSection>& sections);

/// Writes FormatShapesCsv(shapes) to path atomically (see WriteFileAtomically).
void WriteShapesCsv(const std::string& path, const std::vector<CaseShape>& shapes);

/// Reads a shapes.csv back, cases in file order. Throws InputError on missing columns, bad
/// numbers, or vertex indices that do not run 0, 1, 2, ... within a case.
std::vector<CaseShape> ReadShapesCsv(const std::string& path);

}  // namespace rodfit

namespace rodfit {

/// A moving case's frames for trajectory.csv and reactions.csv (rodfit simulate with dynamics).
struct CaseMotion {
  std::string name;
  std::vector<double> s;  ///< [m] the vertices' arc lengths
  struct Frame {
    double t = 0.0;
    Eigen::Matrix3Xd x;
    std::vector<CaseForce> reactions;  ///< name, point, s, position, force, moment
  };
  std::vector<Frame> frames;
};

/// `case,t,vertex,s,x,y,z`: every written frame of every case.
std::string FormatTrajectoryCsv(const std::vector<CaseMotion>& motions);
/// `case,t,point,s,x,y,z,fx,fy,fz,mx,my,mz`: the held points' reactions at every written frame.
std::string FormatReactionsCsv(const std::vector<CaseMotion>& motions);

/// One row of a moving scene's summary.csv: `case,completed,steps,newton_iterations,
/// stable_step,reason`.
struct MotionSummaryRow {
  std::string name;
  bool completed = false;
  int steps = 0;
  int newton_iterations = 0;
  double stable_step = 0.0;  ///< [s] explicit: the stable step at the start; else 0
  std::string reason;
};
std::string FormatMotionSummaryCsv(const std::vector<MotionSummaryRow>& rows);

}  // namespace rodfit
