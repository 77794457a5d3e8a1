// `--format json`: the profile itself, re-written with two-space indentation after the same
// checks as every other export (ValidateForExport): what the runtime, `simulate` and the other
// formats would refuse, json refuses too.
#include <string>

#include <nlohmann/json.hpp>

#include "export_format.h"

namespace rodfit {
namespace {

std::string WriteJson(const ExportInput& input) {
  const nlohmann::json doc = nlohmann::json::parse(input.profile_text);
  ExportNumbers(input.profile, "json").Check(doc);
  return doc.dump(2) + "\n";
}

}  // namespace

ExportFormat JsonExport() {
  return {"json", "the profile itself, validated as the runtime reads it (JSON)",
          /*needs_time_step=*/false, /*takes_time_step=*/false, /*takes_overrides=*/false,
          &WriteJson};
}

}  // namespace rodfit
