// The parameter table (material_parameters.h).
#include "rodfit/model/material_parameters.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace rodfit {
const std::vector<MaterialParameterInfo>& MaterialParameters() {
  using K = ParameterKind;
  static const std::vector<MaterialParameterInfo> rows = {
      {"bend_stiffness", "N m^2", true, true, false, K::kRodStiffness, 0, nullptr,
       &Material::bend_stiffness, nullptr, "B1, bending about d1",
       kMinParameterValue, kMaxParameterValue},
      {"bend_stiffness_2", "N m^2", true, false, false, K::kRodStiffness, 1, "bend_stiffness",
       nullptr, nullptr, "B2, bending about d2 (absent: B1)",
       kMinParameterValue, kMaxParameterValue},
      {"twist_stiffness", "N m^2", true, true, false, K::kRodStiffness, 2, nullptr,
       &Material::twist_stiffness, nullptr, "GJ, torsion",
       kMinParameterValue, kMaxParameterValue},
      {"stretch_stiffness", "N", true, true, false, K::kRodStiffness, 3, nullptr,
       &Material::stretch_stiffness, nullptr, "EA, stretch",
       kMinParameterValue, kMaxParameterValue},
      {"spring_stiffness", "N/m^2", false, false, false, K::kSpring, -1, nullptr,
       &Material::spring_stiffness, nullptr,
       "K, tissue springs of zones without a parameter of their own",
       kMinParameterValue, kMaxParameterValue},
      {"ring_bend_stiffness", "N m^2", true, true, true, K::kRing, 1, nullptr,
       &Material::ring_bend_stiffness, nullptr, "kb, bending of the section ring",
       kMinParameterValue, kMaxParameterValue},
      {"ring_stretch_stiffness", "N", true, true, true, K::kRing, 2, nullptr,
       &Material::ring_stretch_stiffness, nullptr, "ks, stretch of the section ring",
       kMinParameterValue, kMaxParameterValue},
      {"damping", "N s/m^2", false, false, false, K::kDamping, -1, nullptr, &Material::damping,
       nullptr, "c, external viscous drag per length",
       kMinParameterValue, kMaxParameterValue},
      {"bend_damping", "N m^2 s", false, false, false, K::kDamping, -1, nullptr,
       &Material::bend_damping, nullptr, "eta_B, viscosity of the bending rates",
       kMinParameterValue, kMaxParameterValue},
      {"twist_damping", "N m^2 s", false, false, false, K::kDamping, -1, nullptr,
       &Material::twist_damping, nullptr, "eta_GJ, viscosity of the twist rate",
       kMinParameterValue, kMaxParameterValue},
      {"stretch_damping", "N s", false, false, false, K::kDamping, -1, nullptr,
       &Material::stretch_damping, nullptr, "eta_EA, viscosity of the stretch rate",
       kMinParameterValue, kMaxParameterValue},
      {"linear_density", "kg/m", true, false, false, K::kMass, -1, nullptr, nullptr,
       &RodSpec::linear_density, "rho A, the rod's mass per length (a moving scene's parameter)",
       kMinLinearDensity, kMaxLinearDensity},
  };
  return rows;
}

std::string CheckMaterialParameterRange(const MaterialParameterInfo& row, double value,
                                       const std::string& note) {
  auto show = [](double v) {
    char text[32];
    std::snprintf(text, sizeof(text), "%g", v);
    return std::string(text);
  };
  if (!std::isfinite(value)) return "must be finite (is " + show(value) + ")" + note;
  if (value == 0.0 && !row.positive) return "";  // the term off
  if (value >= row.lowest && value <= row.highest) return "";
  const std::string head = value > row.highest ? show(value) + " is beyond " + show(row.highest)
                                               : show(value) + " is below " + show(row.lowest);
  return head + note + ", outside " + row.name + "'s physical range [" + show(row.lowest) + ", " +
         show(row.highest) + "] " + row.unit + (row.positive ? "" : " (or 0: off)");
}

const MaterialParameterInfo* FindMaterialParameter(const std::string& name) {
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (name == row.name) return &row;
  return nullptr;
}

const char* MaterialParameterUnit(const std::string& name) {
  const MaterialParameterInfo* row = FindMaterialParameter(name);
  return row ? row->unit : "N/m^2";  // a spring zone's own stiffness
}

std::optional<double> MaterialParameterValue(const Material& material, const std::string& name,
                                             const RodSpec* rod) {
  if (const MaterialParameterInfo* row = FindMaterialParameter(name)) {
    if (row->rod_field) return rod ? std::optional<double>(rod->*(row->rod_field)) : std::nullopt;
    return row->field ? std::optional<double>(material.*(row->field)) : material.bend_stiffness_2;
  }
  const auto it = material.spring_parameters.find(name);
  if (it != material.spring_parameters.end()) return it->second;
  return std::nullopt;
}

double EffectiveMaterialParameter(const Material& material, const std::string& name,
                                  const RodSpec* rod) {
  if (name == "bend_stiffness_2") return material.B2();
  const std::optional<double> v = MaterialParameterValue(material, name, rod);
  if (!v) throw std::invalid_argument("'" + name.substr(0, 60) + "' is not a material parameter");
  return *v;
}

void AssignMaterialParameter(const std::string& name, double value, Material* material,
                             RodSpec* rod) {
  const MaterialParameterInfo* row = FindMaterialParameter(name);
  if (!row) {
    material->spring_parameters[name] = value;
  } else if (row->rod_field) {
    if (!rod) throw std::invalid_argument(name + " is the rod's: set it on a RodSpec");
    rod->*(row->rod_field) = value;
  } else if (row->field) {
    material->*(row->field) = value;
  } else {
    material->bend_stiffness_2 = value;
  }
}

const Parameter* FindParameter(const std::vector<Parameter>& parameters, const std::string& name) {
  for (const Parameter& p : parameters)
    if (p.name == name) return &p;
  return nullptr;
}

RoundSectionConstants DeriveRoundSection(const Material& material, double radius) {
  RoundSectionConstants c;
  c.radius = radius;
  const double r2 = radius * radius;
  const double area = M_PI * r2;
  const double second_moment = 0.25 * M_PI * r2 * r2;  // I of a disc about a diameter [m^4]
  const double polar_moment = 2.0 * second_moment;     // J [m^4]
  const double b1 = material.B1(), b2 = material.B2();
  c.youngs_modulus = 0.5 * (b1 + b2) / second_moment;
  c.youngs_modulus_stretch = material.stretch_stiffness / area;
  c.shear_modulus = material.twist_stiffness / polar_moment;
  c.poisson_ratio = c.youngs_modulus / (2.0 * c.shear_modulus) - 1.0;
  auto percent = [](double ratio) {
    char buffer[32];
    std::snprintf(buffer, sizeof(buffer), "%.3g", 100.0 * ratio);
    return std::string(buffer);
  };
  std::string why;
  auto add = [&why](const std::string& reason) { why += (why.empty() ? "" : "; ") + reason; };
  if (std::abs(b1 - b2) > kRoundSectionTolerance * 0.5 * (b1 + b2))
    add("B1 and B2 differ by " + percent(std::abs(b1 - b2) / (0.5 * (b1 + b2))) +
        " % (a round section bends alike about both axes)");
  const double stretch_ratio = c.youngs_modulus_stretch / c.youngs_modulus;
  if (std::abs(stretch_ratio - 1.0) > kRoundSectionTolerance)
    add("E from EA is " + percent(stretch_ratio) + " % of E from B");
  // An isotropic solid has -1 < nu <= 1/2 (a positive bulk and shear modulus).
  if (!(c.poisson_ratio > -1.0 && c.poisson_ratio <= 0.5))
    add("Poisson's ratio " + percent(c.poisson_ratio / 100.0) + " is outside (-1, 0.5]");
  c.consistent = why.empty();
  c.inconsistency = why;
  return c;
}

}  // namespace rodfit
