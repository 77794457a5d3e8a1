// Reading a profile JSON back (docs/formats.md, "Profile JSON"): the validating reader a
// simulator uses to rebuild the fitted rod. It returns the model layer's description — a Scene
// with the rod, the material, gravity, the spring zones, the section and one case holding the
// rod's held ends and cuts — and the parameters as the profile states them. Every check names the
// file and the JSON key in one line (`p.json: parameters.bend_stiffness.value: must be > 0`).
//
// A parameter the fit could not determine is written with `identifiable: false` and
// `value: null`; the reader never invents a value for it: the caller supplies one through
// ProfileReadOptions::overrides (the CLI's `--set name=value`), or the read fails.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "rodfit/model/material_parameters.h"
#include "rodfit/model/scene.h"

namespace rodfit {

/// Versions of the profile format this reader accepts.
inline constexpr int kProfileMinVersion = 1;
inline constexpr int kProfileMaxVersion = 2;
/// Largest profile file read [bytes]; a fitted profile is a few kB.
inline constexpr std::uintmax_t kMaxProfileBytes = std::uintmax_t{4} << 20;

/// A profile that cannot be used. what() is one line: `FILE: KEY: message`.
struct ProfileError : std::runtime_error {
  ProfileError(const std::string& file, const std::string& key, const std::string& message);
  std::string file, key, message;
};

struct ProfileReadOptions {
  /// Values [SI, the parameter's unit] that replace the profile's, by parameter name; the only
  /// way to use a profile with an undetermined parameter. A name the profile does not list is
  /// an error (a typo must not pass silently).
  std::map<std::string, double> overrides;
};


struct Profile {
  std::string path;
  int version = 0;
  std::string rodfit_version;
  /// rod, material, gravity, springs, section, and cases[0] = the held boundary ("held" in the
  /// profile: clamp, end clamp or end pin, pins, cuts; no loads). Version 1 profiles have no
  /// held ends, zones or section: the clamp at the origin along x with d1 = z, no springs.
  Scene scene;
  /// `parameters` as read, in the profile's order (after overrides): value (what the rod uses),
  /// std (when the fit gave one), fit (the profile's `fitted`), identifiable, tied_to
  /// ("bend_stiffness" for an isotropic B2), overridden (by ProfileReadOptions::overrides).
  std::vector<Parameter> parameters;
  const Parameter* Find(const std::string& name) const;
};

/// Reads and validates a profile file. Throws ProfileError.
Profile LoadProfile(const std::string& path, const ProfileReadOptions& options = {});

/// The same from the file's text; `path` names it in messages.
Profile ParseProfile(const std::string& text, const std::string& path,
                     const ProfileReadOptions& options = {});

/// Puts the profile's material into `scene` in place of the scene's own parameters (what
/// `rodfit simulate SCENE --profile P` does). The scene keeps its cases, springs, section and
/// gravity; its rod must be the profile's (length, segments, radius, linear density: a scene read
/// with parameters optional may leave the density out, NaN, and takes the profile's; a scene
/// without a rest shape takes the profile's `rod.rest_shape`, one with another is refused), and
/// every spring zone's own parameter must be in the profile. Throws ProfileError naming the
/// profile's key.
void UseProfileMaterial(const Profile& profile, Scene* scene);

/// Parses `name=value` (the CLI's --set) into *overrides; false with *why on a malformed one.
bool ParseOverride(const std::string& text, std::map<std::string, double>* overrides,
                   std::string* why);

}  // namespace rodfit
