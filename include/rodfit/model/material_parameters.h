// The parameter table (docs/model.md, "Stiffnesses"; docs/formats.md, "Profile JSON"): one row
// per material parameter with its name as the files spell it, its SI unit, its lower bound and the
// Material field it sets. The profile writer and the runtime's profile reader loop over these rows
// instead of spelling the names out again. A spring zone's own parameter (a name the scene gives
// in `springs:`) is not a row: it is a spring stiffness, read and written like spring_stiffness.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "rodfit/model/scene.h"

namespace rodfit {

/// What a parameter acts on: which model term it sets, hence which solver can see it.
enum class ParameterKind {
  kRodStiffness,  ///< the rod's elastic energy (statics and dynamics)
  kSpring,        ///< the tissue springs of zones without a parameter of their own
  kRing,          ///< the cross-section ring (seen only through a poke's dented section)
  kDamping,       ///< damping, read by the dynamics only (>= 0; 0 turns the term off)
};

struct MaterialParameterInfo {
  const char* name;         ///< key in `parameters:` and in the profile
  const char* unit;         ///< SI unit as written in the profile ("N m^2", ...)
  bool positive;            ///< true: must be > 0; false: >= 0 (0 turns the term off)
  /// Needed to build a rod: bend, twist and stretch stiffness (the ring's two with a section).
  bool required;
  bool needs_section;       ///< only read when the scene has a cross-section (ring stiffness)
  ParameterKind kind;
  /// kRodStiffness: the stiffness term it sets, 0 B1, 1 B2, 2 GJ, 3 EA (the order of the
  /// statics' sensitivities, solve/sensitivity.h); kRing: 1 bend, 2 stretch; otherwise -1.
  int term;
  /// A row whose absence ties it to another row's value (bend_stiffness_2 to bend_stiffness:
  /// an isotropic section), or null.
  const char* tied_to;
  /// The Material member it sets; null for bend_stiffness_2, an optional (absent: tied).
  double Material::*field;
  const char* description;  ///< what it sets, for messages and docs
};

/// Every row, in the order the profile lists them.
const std::vector<MaterialParameterInfo>& MaterialParameters();

/// The row of `name`, or null (a spring zone's own parameter, or an unknown name).
const MaterialParameterInfo* FindMaterialParameter(const std::string& name);

/// Unit of a parameter: the row's, or "N/m^2" for a spring zone's own parameter.
const char* MaterialParameterUnit(const std::string& name);

/// The value a material holds for `name` (a row or a key of Material::spring_parameters);
/// nullopt for bend_stiffness_2 when it is tied to bend_stiffness, or an unknown name.
std::optional<double> MaterialParameterValue(const Material& material, const std::string& name);

/// The value in effect for `name`: as MaterialParameterValue, but a tied row gives the value of
/// the row it is tied to (bend_stiffness_2 absent: B1). Throws std::invalid_argument for a name
/// that is neither a row nor a spring zone's own parameter.
double EffectiveMaterialParameter(const Material& material, const std::string& name);

/// Sets `name` (a row, or else a spring zone's own parameter) to `value`.
void AssignMaterialParameter(const std::string& name, double value, Material* material);

/// Engineering constants of a solid round section of one isotropic material that has the rod's
/// stiffnesses: I = pi r^4 / 4, J = 2 I, A = pi r^2; E = B / I (B the mean of B1 and B2),
/// G = GJ / J, nu = E / (2 G) - 1, and E again from the stretch, EA / A. A real thread (braided,
/// twisted) or a tissue tube is not such a section: `consistent` says whether the stiffnesses
/// agree with one, within kRoundSectionTolerance, and `inconsistency` says why not.
struct RoundSectionConstants {
  double radius = 0.0;                  ///< [m]
  double youngs_modulus = 0.0;          ///< [Pa] from bending, (B1 + B2) / 2 / I
  double youngs_modulus_stretch = 0.0;  ///< [Pa] from stretch, EA / A
  double shear_modulus = 0.0;           ///< [Pa] GJ / J
  double poisson_ratio = 0.0;           ///< [-] E / (2 G) - 1 (E from bending)
  bool consistent = false;
  std::string inconsistency;            ///< empty when consistent
};

/// Relative disagreement allowed between B1 and B2 and between the two Young's moduli before
/// the constants are flagged: a fitted stiffness carries a few percent of uncertainty, so exact
/// equality would flag every fitted thread.
inline constexpr double kRoundSectionTolerance = 0.1;

/// The constants of `material` for a round section of `radius` (> 0); B1, GJ, EA must be > 0.
RoundSectionConstants DeriveRoundSection(const Material& material, double radius);

}  // namespace rodfit
