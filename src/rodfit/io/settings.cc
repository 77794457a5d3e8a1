// The settings' declarations (settings.h): one Serialize per configuration.
#include "rodfit/io/settings.h"

#include <cstdio>

namespace rodfit {
namespace {

std::string Show(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.10g", v);
  return buffer;
}

// "a, b or c".
std::string JoinOr(const std::vector<std::string>& words) {
  std::string out;
  for (size_t k = 0; k < words.size(); ++k)
    out += (k == 0 ? "" : k + 1 == words.size() ? " or " : ", ") + words[k];
  return out;
}

}  // namespace

void Serialize(SettingsArchive* a, StaticsOptions* o) {
  a->Integer("max_iterations", &o->max_iterations, 1, 100000);
  a->Number("gradient_tolerance", &o->gradient_tolerance, 1e-16, 1e-2);
  a->Number("step_tolerance", &o->step_tolerance, 1e-16, 1e-2);
  a->Bool("escape_saddles", &o->escape_saddles);
}

void Serialize(SettingsArchive* a, FitOptions* o) {
  const std::vector<RobustLoss> losses = {RobustLoss::kNone, RobustLoss::kHuber,
                                          RobustLoss::kCauchy, RobustLoss::kSoftL1};
  std::vector<std::string> names;
  int index = 0;
  for (size_t k = 0; k < losses.size(); ++k) {
    names.push_back(RobustLossName(losses[k]));
    if (losses[k] == o->loss) index = static_cast<int>(k);
  }
  // The profile carries the settings that say what its std and rms mean (its spelling of
  // trusted_sigmas is older than the YAML key's).
  a->Carry("loss", "loss");
  a->Choice("loss", &index, names, "must be " + JoinOr(names));
  o->loss = losses[index];
  a->Carry("loss_scale", "loss_scale");
  a->Positive("loss_scale", &o->loss_scale);
  a->Bool("global", &o->global);
  a->Integer("max_iterations", &o->max_iterations, 1, kMaxFitIterations);
  a->Carry("trusted_sigmas", "sigmas_trusted");
  a->Bool("trusted_sigmas", &o->trusted_sigmas);
}

void Serialize(SettingsArchive* a, DynamicsSpec* d, const std::vector<std::string>& integrators) {
  a->Require("time_step");
  a->Number("time_step", &d->time_step, 1e-12, 10.0);
  a->Require("duration");
  a->Number("duration", &d->duration, 0.0, 1e6);
  a->Check(d->duration / d->time_step <= kMaxDynamicSteps, "time_step",
           "gives " + Show(d->duration / d->time_step) + " steps, above the limit of " +
               Show(kMaxDynamicSteps));
  // The registered schemes, and `implicit` for the default implicit one.
  std::vector<std::string> words = integrators;
  words.insert(words.begin() + 1, "implicit");
  std::vector<std::string> names = words;
  names[1] = kDefaultIntegrator;
  int index = 0;
  for (size_t k = 0; k < names.size(); ++k)
    if (names[k] == d->integrator) index = static_cast<int>(k);
  a->Choice("integrator", &index, words, "must be " + JoinOr(words));
  d->integrator = names[index];
  a->Count("output_every", &d->output_every, 1, 100000000);
  a->Bool("substep", &d->substep);
  a->Check(!d->substep || d->integrator == "explicit", "substep",
           "is for the explicit integrator only");
  a->Check(!a->Has("max_halvings") || d->integrator != "explicit", "max_halvings",
           "is for the implicit integrators only");
  a->Count("max_halvings", &d->max_halvings, 0, kMaxStepHalvings);
  a->Check(!a->Has("error_tolerance") || d->integrator != "explicit", "error_tolerance",
           "is for the implicit integrators only");
  a->Number("error_tolerance", &d->error_tolerance, 0.0, 1.0);
  a->Number("min_time_step", &d->min_time_step, 1e-12, d->time_step);
}

}  // namespace rodfit
