// Settings declared once (docs/formats.md, the `solver:`, `fit:` and `dynamics:` rows): each
// configuration's Serialize visits its fields — the key, the field, its range — on an archive.
// The experiment reader runs it with an archive over the YAML block (each value checked, a
// failure naming the file, line and key; a key not declared is unknown), and
// tests/io/settings_docs_test.cc with one that checks every key's row of docs/formats.md names
// its range and its default. The defaults are the structs' own initializers (StaticsOptions,
// FitOptions, DynamicsSpec), the one place each is declared.
#pragma once

#include <string>
#include <vector>

#include "rodfit/fit/fit.h"
#include "rodfit/model/scene.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

class SettingsArchive {
 public:
  virtual ~SettingsArchive() = default;
  /// Reading a block (the experiment reader); otherwise only the keys and their ranges are
  /// visited (the values are the defaults).
  virtual bool reading() const = 0;
  /// An integer in [lo, hi] ("must be an integer in [lo, hi]").
  virtual void Integer(const char* key, int* value, int lo, int hi) = 0;
  /// An integer, then in [lo, hi] ("expected an integer", then "must be in [lo, hi]").
  virtual void Count(const char* key, int* value, int lo, int hi) = 0;
  /// A number in [lo, hi] ([s], [1], ... as the key's row says).
  virtual void Number(const char* key, double* value, double lo, double hi) = 0;
  /// A number > 0.
  virtual void Positive(const char* key, double* value) = 0;
  virtual void Bool(const char* key, bool* value) = 0;
  /// One of `words`: *index becomes its position. `expected` is the message of another word
  /// (e.g. "must be explicit, implicit, backward_euler, midpoint or bdf2").
  virtual void Choice(const char* key, int* index, const std::vector<std::string>& words,
                      const std::string& expected) = 0;
  /// A key the block must give.
  virtual void Require(const char* key) = 0;
  /// Whether the block gives the key.
  virtual bool Has(const char* key) const = 0;
  /// Reading: an error at `key` unless `ok` (at the block when it does not give the key).
  virtual void Check(bool ok, const char* key, const std::string& message) = 0;
};

/// `solver:` — the static solves' settings.
void Serialize(SettingsArchive* a, StaticsOptions* o);

/// `fit:` — the identification's settings (loss, loss_scale, global, max_iterations,
/// trusted_sigmas).
void Serialize(SettingsArchive* a, FitOptions* o);

/// `dynamics:` — the integration in time (time_step and duration required). `integrators`: the
/// registered schemes' names in the registry's order (IntegratorNames(),
/// rodfit/solve/integrator.h), given by the caller so that io links no solver.
void Serialize(SettingsArchive* a, DynamicsSpec* d, const std::vector<std::string>& integrators);

/// The fit's and the dynamics' limits the blocks check.
inline constexpr int kMaxFitIterations = 10000;   ///< fit.max_iterations
inline constexpr double kMaxDynamicSteps = 1e8;   ///< duration / time_step: beyond, hours of run

}  // namespace rodfit
