// The registry of time integrators (integrator.h): a new scheme is one file and one line below.
#include "rodfit/solve/integrator.h"

#include <cstring>

namespace rodfit {
namespace {

using Factory = const TimeIntegrator& (*)();

// The registered schemes: one line each.
constexpr Factory kIntegrators[] = {
    &StormerVerletIntegrator,
    &BackwardEulerIntegrator,
    &MidpointIntegrator,
    &Bdf2Integrator,
};

}  // namespace

const TimeIntegrator* FindIntegrator(const std::string& name) {
  for (Factory f : kIntegrators)
    if (name == f().name()) return &f();
  return nullptr;
}

std::vector<std::string> IntegratorNames() {
  std::vector<std::string> names;
  for (Factory f : kIntegrators) names.push_back(f().name());
  return names;
}

}  // namespace rodfit
