// The parameter table (docs/model.md, "Stiffnesses"; docs/formats.md, "Profile JSON"): one row
// per parameter of the model with its name as the files spell it, its SI unit, its lower bound and
// what it sets in the model (a Material member, or the rod's linear density); and the one record
// of a parameter's value through every layer (Parameter): as the experiment gives it, as the fit
// starts from and estimates it, as the profile stores it and the runtime reads it back. The
// experiment reader, the fits, the profile writer and reader and the report loop over these rows
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
  kMass,          ///< the rod's linear density: a parameter only of a moving scene's fit
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
  /// The Material member it sets; null for bend_stiffness_2, an optional (absent: tied), and
  /// for a row of the rod.
  double Material::*field;
  /// The RodSpec member it sets (linear_density), or null.
  double RodSpec::*rod_field;
  const char* description;  ///< what it sets, for messages and docs
};

/// Every row, in the order the profile lists them (the material's, then the rod's density).
const std::vector<MaterialParameterInfo>& MaterialParameters();

/// The row of `name`, or null (a spring zone's own parameter, or an unknown name).
const MaterialParameterInfo* FindMaterialParameter(const std::string& name);

/// Whether a row is part of a moving thread's model: its stiffnesses, its damping and its mass
/// (the springs and the ring are not). The rows a motion fit fits (fit/motion_fit.h) and a motion
/// fit file holds (io/recording.h).
inline bool InMotionModel(const MaterialParameterInfo& row) {
  return row.kind == ParameterKind::kRodStiffness || row.kind == ParameterKind::kDamping ||
         row.kind == ParameterKind::kMass;
}

/// Unit of a parameter: the row's, or "N/m^2" for a spring zone's own parameter.
const char* MaterialParameterUnit(const std::string& name);

/// The value a scene's material (or, for a row of the rod, its rod) holds for `name` (a row or a
/// key of Material::spring_parameters); nullopt for bend_stiffness_2 when it is tied to
/// bend_stiffness, a row of the rod without `rod`, or an unknown name.
std::optional<double> MaterialParameterValue(const Material& material, const std::string& name,
                                             const RodSpec* rod = nullptr);

/// The value in effect for `name`: as MaterialParameterValue, but a tied row gives the value of
/// the row it is tied to (bend_stiffness_2 absent: B1). Throws std::invalid_argument for a name
/// that is neither a row nor a spring zone's own parameter.
double EffectiveMaterialParameter(const Material& material, const std::string& name,
                                  const RodSpec* rod = nullptr);

/// Sets `name` (a row, or else a spring zone's own parameter) to `value` where its row says: in
/// `material`, or in `rod` for a row of the rod (std::invalid_argument without one).
void AssignMaterialParameter(const std::string& name, double value, Material* material,
                             RodSpec* rod = nullptr);

/// One parameter as an experiment gives it and a fit reports it: a row of the table above or a
/// spring zone's own stiffness. The one record of a parameter's value in every layer (the
/// experiment's `parameters:`, the fit's input and result, the profile and its reader).
struct Parameter {
  std::string name;
  /// [its unit] As given (the value a fit starts from, or holds when not fitted), then as the
  /// fit estimates it; for a parameter not identifiable, where the fit stopped (see reason).
  double value = 0.0;
  bool fit = false;                ///< fitted (in log space), or held at value
  std::optional<double> min, max;  ///< a fitted value's bounds, min < max
  double start = 0.0;              ///< where the fit started (the given value)
  std::optional<double> std;       ///< present only for a fitted, identifiable parameter
  bool identifiable = true;        ///< false: the data do not determine it
  std::string reason;              ///< why not identifiable
  bool at_bound = false;           ///< the estimate lies on min or max
  std::string tied_to;             ///< absent, it follows this row (bend_stiffness_2)
  bool overridden = false;         ///< its value replaced the file's (a profile read with --set)
  int line = 0;                    ///< 1-based line of the experiment file that gives it, or 0

  const char* unit() const { return MaterialParameterUnit(name); }
};

/// The parameter named `name` among `parameters`, or null.
const Parameter* FindParameter(const std::vector<Parameter>& parameters, const std::string& name);

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
