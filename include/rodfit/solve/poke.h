// The local deformation of a poked tissue (docs/model.md, "Cross-section"): the cross-section
// ring at the poke's arc length, placed on the solved rod with its material frame, deformed by
// the in-plane part of the instrument force; and the tube surface mesh swept along the rod with
// that deformation propagated by eqs. 12–13.
#pragma once

#include "rodfit/model/cross_section.h"
#include "rodfit/model/rod.h"
#include "rodfit/model/tube_mesh.h"
#include "rodfit/solve/ring.h"

namespace rodfit {

struct PokeResult {
  SectionPlacement placement;   ///< the section in the world
  RingResult ring;              ///< section coordinates, summary, sensitivities
  Eigen::Matrix3Xd rest_world;  ///< rest ring nodes [m]
  Eigen::Matrix3Xd deformed_world;  ///< deformed ring nodes [m]
};

/// Solves the ring of the case's poke on the equilibrium `state`. The model's case must have a
/// poke. Throws std::invalid_argument for an invalid section or stiffness.
PokeResult SolvePoke(const RodModel& model, const RodState& state, const SectionSpec& section,
                     const RingStiffness& stiffness);

/// The tube surface (radius = section radius, one ring of section.nodes vertices per rod
/// vertex) with the poke's deformation propagated (eqs. 12-13).
TubeMesh PokedTube(const RodModel& model, const RodState& state, const SectionSpec& section,
                   const PokeResult& poke);

}  // namespace rodfit
