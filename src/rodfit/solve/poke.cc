// Poke: ring on the solved rod, and the deformed tube (poke.h).
#include "rodfit/solve/poke.h"

#include <stdexcept>

namespace rodfit {

PokeResult SolvePoke(const RodModel& model, const RodState& state, const SectionSpec& section,
                     const RingStiffness& stiffness) {
  if (!model.load_case().poke) throw std::invalid_argument("case has no poke");
  const Poke& poke = *model.load_case().poke;
  PokeResult r;
  r.placement = SectionAt(model, state, poke.s);
  r.ring = SolveRing(section, stiffness, ProjectToSection(poke.force, r.placement));
  r.rest_world = SectionToWorld(r.ring.rest, r.placement);
  r.deformed_world = SectionToWorld(r.ring.nodes, r.placement);
  return r;
}

TubeMesh PokedTube(const RodModel& model, const RodState& state, const SectionSpec& section,
                   const PokeResult& poke) {
  const TubeMesh tube = BuildTube(model, state, section.radius, section.nodes);
  return PropagateLocalDeformation(tube, poke.placement, section, poke.ring).mesh;
}

}  // namespace rodfit
