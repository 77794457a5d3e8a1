// The parameter table (material_parameters.h).
#include "rodfit/model/material_parameters.h"

#include <cmath>
#include <cstdio>

namespace rodfit {
namespace {

// Where each row's value lives in Material; bend_stiffness_2 is optional (absent: tied to B1).
double* Field(const std::string& name, Material* m) {
  if (name == "bend_stiffness") return &m->bend_stiffness;
  if (name == "twist_stiffness") return &m->twist_stiffness;
  if (name == "stretch_stiffness") return &m->stretch_stiffness;
  if (name == "spring_stiffness") return &m->spring_stiffness;
  if (name == "ring_bend_stiffness") return &m->ring_bend_stiffness;
  if (name == "ring_stretch_stiffness") return &m->ring_stretch_stiffness;
  if (name == "damping") return &m->damping;
  if (name == "bend_damping") return &m->bend_damping;
  if (name == "twist_damping") return &m->twist_damping;
  if (name == "stretch_damping") return &m->stretch_damping;
  return nullptr;
}

}  // namespace

const std::vector<MaterialParameterInfo>& MaterialParameters() {
  static const std::vector<MaterialParameterInfo> rows = {
      {"bend_stiffness", "N m^2", true, true, false, "B1, bending about d1"},
      {"bend_stiffness_2", "N m^2", true, false, false, "B2, bending about d2 (absent: B1)"},
      {"twist_stiffness", "N m^2", true, true, false, "GJ, torsion"},
      {"stretch_stiffness", "N", true, true, false, "EA, stretch"},
      {"spring_stiffness", "N/m^2", false, false, false,
       "K, tissue springs of zones without a parameter of their own"},
      {"ring_bend_stiffness", "N m^2", true, true, true, "kb, bending of the section ring"},
      {"ring_stretch_stiffness", "N", true, true, true, "ks, stretch of the section ring"},
      {"damping", "N s/m^2", false, false, false, "c, external viscous drag per length"},
      {"bend_damping", "N m^2 s", false, false, false, "eta_B, viscosity of the bending rates"},
      {"twist_damping", "N m^2 s", false, false, false, "eta_GJ, viscosity of the twist rate"},
      {"stretch_damping", "N s", false, false, false, "eta_EA, viscosity of the stretch rate"},
  };
  return rows;
}

const MaterialParameterInfo* FindMaterialParameter(const std::string& name) {
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (name == row.name) return &row;
  return nullptr;
}

const char* MaterialParameterUnit(const std::string& name) {
  const MaterialParameterInfo* row = FindMaterialParameter(name);
  return row ? row->unit : "N/m^2";
}

std::optional<double> MaterialParameterValue(const Material& material, const std::string& name) {
  if (name == "bend_stiffness_2") return material.bend_stiffness_2;
  // Field() only locates the member; nothing is written through it here.
  if (const double* f = Field(name, const_cast<Material*>(&material))) return *f;
  const auto it = material.spring_parameters.find(name);
  if (it != material.spring_parameters.end()) return it->second;
  return std::nullopt;
}

void AssignMaterialParameter(const std::string& name, double value, Material* material) {
  if (name == "bend_stiffness_2") {
    material->bend_stiffness_2 = value;
  } else if (double* f = Field(name, material)) {
    *f = value;
  } else {
    material->spring_parameters[name] = value;
  }
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
