// The profile JSON (docs/formats.md, "Profile JSON"), what a simulator imports: the rod, every
// parameter the model used (value, std, fitted flag, unit, identifiability), correlations and the
// fit summary with a digest of the input files.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"

namespace rodfit {

/// The profile format's version that ProfileJson writes (2: the held ends, spring zones, section
/// and derived constants; the runtime reads 1 and 2).
inline constexpr int kProfileVersion = 2;

/// FNV-1a 64-bit digest of a file's bytes as 16 hex digits (identifies the inputs of a fit; not
/// a cryptographic hash). Throws InputError when the file cannot be read or is not a regular file
/// of at most kMaxInputFileBytes (never reads a device or FIFO).
std::string FileDigest(const std::string& path);

/// The profile document of a fit's result under `options`; `check` is the fit's verdict on its
/// residuals (CheckResiduals(result, options), rodfit/fit/fit.h: the caller's, so that io, which
/// writes it, links no fit).
nlohmann::json ProfileJson(const Experiment& experiment, const FitOptions& options,
                           const FitResult& result, const ResidualCheck& check);

/// Its text as written: two-space indented JSON and a final newline.
std::string FormatProfile(const nlohmann::json& profile);

/// Writes it atomically (temporary file, then rename).
void WriteProfile(const std::string& path, const nlohmann::json& profile);

}  // namespace rodfit
