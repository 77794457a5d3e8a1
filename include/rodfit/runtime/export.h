// A profile in the terms other simulation engines take (docs/formats.md, "Exports";
// `rodfit export`). Formats are a registry: each is one file in src/rodfit/runtime/
// (export_FORMAT.cc) and one line in ExportFormats(); the CLI's --format, its help and the
// checks of its options come from the rows. Every export runs the same checks first
// (ValidateForExport: the profile as the runtime and `simulate` would take it), and every number a
// format writes is checked again as it is written (finite, at most kMaxExportMagnitude), so an
// export never carries a NaN, an infinity or an absurd value into another engine.
#pragma once

#include <string>
#include <vector>

#include "rodfit/runtime/profile.h"

namespace rodfit {

/// Largest magnitude of any number an export writes: beyond it a value is a unit or typing
/// mistake, and another engine's arithmetic on it overflows.
inline constexpr double kMaxExportMagnitude = 1e100;
/// Largest magnitude of a profile's parameter value an export accepts (the rod model's own
/// envelope for stiffnesses, applied to every parameter, damping included).
inline constexpr double kMaxExportParameter = 1e30;
/// The time step a scene export (sofa, mujoco) writes when none is given [s]: a haptic rate's
/// 1 kHz, or less where the format says its engine needs less (mujoco).
inline constexpr double kDefaultExportTimeStep = 1e-3;

/// What an export takes besides the profile.
struct ExportOptions {
  /// [s] the engine's (sub)step; 0 = the format's default (a format with needs_time_step refuses
  /// 0). Checked: finite and in [1e-9, 10].
  double time_step = 0.0;
};

/// The profile as read and its file's text (the json format re-writes the text).
struct ExportInput {
  const Profile& profile;
  const std::string& profile_text;
  ExportOptions options;
};

/// One export format.
struct ExportFormat {
  const char* name;          ///< --format NAME
  const char* summary;       ///< one line: what the file is (the CLI's help)
  bool needs_time_step;      ///< --time-step required
  bool takes_time_step;      ///< --time-step accepted
  bool takes_overrides;      ///< --set accepted (json writes the profile as fitted)
  /// Writes the file's text from a validated profile. Throws ProfileError (FILE: KEY: message).
  std::string (*write)(const ExportInput& input);
};

/// Every format, in the order docs/formats.md lists them.
const std::vector<ExportFormat>& ExportFormats();

/// The format called `name`, or null.
const ExportFormat* FindExportFormat(const std::string& name);

/// The checks every export runs before anything is written, each a ProfileError naming the profile
/// and its key: the rod model builds from the profile (stiffnesses in the model's range, held
/// points consistent: no two on one vertex), its held shape solves to equilibrium (an end pin 10 m
/// from a 0.2 m rod cannot), rod.radius is in its physical range (CheckRodRadius), and every
/// parameter value is at most kMaxExportParameter.
void ValidateForExport(const Profile& profile);

/// ValidateForExport, then `format`'s writer; throws ProfileError (std::invalid_argument for an
/// unknown format or a bad option). The text is returned: the caller writes it atomically.
std::string Export(const ExportFormat& format, const ExportInput& input);

}  // namespace rodfit
