// A profile in the terms other simulation engines take (docs/formats.md, "Exports";
// `rodfit export`): a SOFA scene snippet for its beam and Cosserat components, per-segment XPBD
// compliances for a position-based stiff rod at a given time step, and the profile itself in
// canonical form. Each returns the file's text; the CLI writes it atomically.
#pragma once

#include <string>

#include "rodfit/runtime/profile.h"

namespace rodfit {

/// SOFA XML snippet (SI units): the rest shape's vertices and edges, UniformMass, Rayleigh
/// damping on the implicit solver, BeamFEMForceField (youngModulus, poissonRatio, radius) and
/// the Cosserat plugin's BeamHookeLawForceField with the same constants, the clamp as a
/// FixedConstraint. The constants are those of a solid round section (DeriveRoundSection);
/// when the stiffnesses do not fit one, the snippet says so in a comment.
std::string FormatSofaSnippet(const Profile& profile);

/// XPBD compliances (JSON) for time step `time_step` [s] (> 0): per segment the stretch
/// compliance l / EA [m/N], per bending vertex the bend and twist compliances l_v / B1,
/// l_v / B2, l_v / GJ [1/(N m)] of the angle constraints between neighbouring frames, each also
/// divided by dt^2 (XPBD's alpha~), the vertex masses, and the spring anchors' compliances.
std::string FormatXpbd(const Profile& profile, double time_step);

/// The profile as read (every key, validated), re-written with two-space indentation.
std::string FormatProfileCanonical(const std::string& profile_text);

}  // namespace rodfit
