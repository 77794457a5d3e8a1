// Settings declared once (docs/formats.md, the `solver:`, `fit:` and `dynamics:` rows): each
// configuration's Serialize visits its fields — the key, the field, its range — on an archive
// (SettingsArchive, rodfit/model/settings_archive.h).
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
#include "rodfit/model/settings_archive.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

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
