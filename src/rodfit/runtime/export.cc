// The export registry and the checks every export runs (rodfit/runtime/export.h), and what the
// formats share (export_format.h). A new format is one file, export_FORMAT.cc defining
// `ExportFormat FORMATExport()`, and one line in ExportFormats() below.
#include "rodfit/runtime/export.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "export_format.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/model/rod_radius.h"

namespace rodfit {

// The formats' own files (export_sofa.cc, ...).
ExportFormat SofaExport();
ExportFormat MujocoExport();
ExportFormat XpbdExport();
ExportFormat JsonExport();

const std::vector<ExportFormat>& ExportFormats() {
  static const std::vector<ExportFormat> formats = {
      SofaExport(),
      MujocoExport(),
      XpbdExport(),
      JsonExport(),
  };
  return formats;
}

const ExportFormat* FindExportFormat(const std::string& name) {
  for (const ExportFormat& f : ExportFormats())
    if (name == f.name) return &f;
  return nullptr;
}

namespace {

std::string Show(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", v);
  return text;
}

}  // namespace

RodModel ExportModel(const Profile& p) {
  try {
    return RodModel(p.scene.rod, p.scene.material, p.scene.gravity, p.scene.cases.front(),
                    p.scene.springs);
  } catch (const std::invalid_argument& e) {
    // The model's own checks: the stiffness envelope, held points on distinct vertices, ...
    throw ProfileError(p.path, "", std::string("the rod cannot be built: ") + e.what());
  }
}

CaseSolution ExportHeldShape(const Profile& p) {
  CaseSolution sol;
  try {
    sol = SolveCase(p.scene, 0, nullptr);
  } catch (const std::invalid_argument& e) {
    throw ProfileError(p.path, "held", std::string("the held rod cannot be built: ") + e.what());
  }
  if (!sol.ok())
    throw ProfileError(p.path, "held",
                       "the rod cannot be brought to equilibrium where its holders hold it (an "
                       "engine would start from that shape): " + sol.summary.BriefReport());
  return sol;
}

std::vector<ExportHolder> ExportHolders(const RodModel& model) {
  std::vector<ExportHolder> out = {{0, "clamp", true}};
  for (const HeldVertex& h : model.held())
    out.push_back({h.vertex, h.Label(), h.kind == HeldVertex::Kind::kEndClamp});
  return out;
}

std::string XmlCommentText(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '\n' || c == '\r') c = ' ';
    if (c == '-' && !out.empty() && out.back() == '-') out += ' ';
    out += c;
  }
  if (!out.empty() && out.back() == '-') out += ' ';  // "-->" must not follow a '-'
  return out;
}

void ExportNumbers::CheckOne(double value, const std::string& field) const {
  if (!std::isfinite(value))
    throw ProfileError(profile_.path, "",
                       "export " + format_ + ": " + field + " would be " + Show(value) +
                           " (not finite); nothing was written");
  if (std::abs(value) > kMaxExportMagnitude)
    throw ProfileError(profile_.path, "",
                       "export " + format_ + ": " + field + " would be " + Show(value) +
                           ", beyond " + Show(kMaxExportMagnitude) +
                           " in magnitude; nothing was written");
}

std::string ExportNumbers::operator()(double value, const std::string& field) const {
  CheckOne(value, field);
  char text[40];
  std::snprintf(text, sizeof(text), "%.17g", value == 0.0 ? 0.0 : value);  // no "-0"
  return text;
}

void ExportNumbers::Check(const nlohmann::json& doc) const {
  std::vector<std::pair<const nlohmann::json*, std::string>> stack = {{&doc, ""}};
  while (!stack.empty()) {
    const auto [node, path] = stack.back();
    stack.pop_back();
    if (node->is_number()) {
      CheckOne(node->get<double>(), path.empty() ? "the document" : path);
    } else if (node->is_object()) {
      for (auto it = node->begin(); it != node->end(); ++it)
        stack.push_back({&it.value(), path.empty() ? it.key() : path + "." + it.key()});
    } else if (node->is_array()) {
      for (size_t i = 0; i < node->size(); ++i)
        stack.push_back({&(*node)[i], path + "[" + std::to_string(i) + "]"});
    }
  }
}

void ValidateForExport(const Profile& p) {
  const RodSpec& rod = p.scene.rod;
  if (rod.radius != 0.0)
    if (const std::string why = CheckRodRadius(rod.radius, rod.length); !why.empty())
      throw ProfileError(p.path, "rod.radius", why);
  for (const Parameter& parameter : p.parameters) {
    if (const MaterialParameterInfo* row = FindMaterialParameter(parameter.name))
      if (const std::string why = CheckMaterialParameterRange(
              *row, parameter.value,
              parameter.overridden ? " (--set " + parameter.name + ")" : std::string());
          !why.empty())
        throw ProfileError(p.path, "parameters." + parameter.name + ".value", why);
    if (!(std::abs(parameter.value) <= kMaxExportParameter))
      throw ProfileError(p.path, "parameters." + parameter.name + ".value",
                         Show(parameter.value) + " is beyond " + Show(kMaxExportParameter) +
                             (parameter.overridden ? " (--set " + parameter.name + ")" : "") +
                             ": no engine takes it");
  }
  // What `simulate` and the runtime build: the model (its envelopes and held-point checks) and
  // the held equilibrium every scene starts from.
  ExportModel(p);
  ExportHeldShape(p);
}

std::string Export(const ExportFormat& format, const ExportInput& input) {
  const double dt = input.options.time_step;
  if (dt != 0.0 && !(dt >= 1e-9 && dt <= 10.0))
    throw std::invalid_argument("--time-step must be in [1e-9, 10] s");
  if (format.needs_time_step && dt == 0.0)
    throw std::invalid_argument(std::string("export --format ") + format.name +
                                " needs --time-step (the simulator's step [s])");
  if (!format.takes_time_step && dt != 0.0)
    throw std::invalid_argument(std::string("--time-step is not for --format ") + format.name);
  ValidateForExport(input.profile);
  return format.write(input);
}

}  // namespace rodfit
