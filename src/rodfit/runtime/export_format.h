// What the export formats share (rodfit/runtime/export.h): the rod as the profile builds it, where
// its holders hold it, and numbers written only when they are finite and in range. Internal to
// the runtime: each format's file (export_FORMAT.cc) includes it.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "rodfit/model/rod.h"
#include "rodfit/runtime/export.h"
#include "rodfit/solve/case_solve.h"

namespace rodfit {

/// The rod with its held ends and nothing else: its rest shape and lumped constants. Throws
/// ProfileError (the model's own checks, naming the profile).
RodModel ExportModel(const Profile& profile);

/// The rod as its holders place it: the profile's case solved to equilibrium (its held points at
/// their targets, under gravity and the springs). Held points other than the clamp sit where the
/// case holds them, not where the straight rest shape would put them, so an engine must start
/// from this shape. Throws ProfileError (key "held") when the case cannot be solved.
CaseSolution ExportHeldShape(const Profile& profile);

/// One held vertex as an export names it: the holder, and whether it holds the frame too.
struct ExportHolder {
  int vertex = 0;
  std::string point;  ///< clamp, end_clamp, end_pin, pins[k]
  bool frame = false; ///< a clamp: position and orientation; else position only
};
/// The clamp first, then the held vertices in the model's order.
std::vector<ExportHolder> ExportHolders(const RodModel& model);

/// `text` (a path) as an XML comment may hold it: no "--" (and no line breaks).
std::string XmlCommentText(const std::string& text);

/// Formats numbers for one export and refuses any that is non-finite or beyond
/// kMaxExportMagnitude, naming the profile, the format and the field written.
class ExportNumbers {
 public:
  ExportNumbers(const Profile& profile, std::string format)
      : profile_(profile), format_(std::move(format)) {}
  /// `value` to 17 significant digits (a round trip), checked; `field` names it in the message.
  std::string operator()(double value, const std::string& field) const;
  /// Every number in `doc` checked, its JSON path naming it.
  void Check(const nlohmann::json& doc) const;

 private:
  void CheckOne(double value, const std::string& field) const;
  const Profile& profile_;
  std::string format_;
};

}  // namespace rodfit
