// The runtime's options (RuntimeOptions, rodfit/runtime/runtime.h): their one declaration, and
// the check of a caller's values against it.
#include <limits>
#include <string>
#include <vector>

#include "rodfit/runtime/runtime.h"

namespace rodfit {

void Serialize(SettingsArchive* a, RuntimeOptions* o) {
  int mode = o->mode == RuntimeMode::kDynamic ? 1 : 0;
  a->Choice("mode", &mode, {"quasi_static", "dynamic"}, "must be quasi_static or dynamic");
  o->mode = mode == 1 ? RuntimeMode::kDynamic : RuntimeMode::kQuasiStatic;
  int tool = o->tool == ToolKind::kPoke ? 1 : 0;
  a->Choice("tool", &tool, {"grasp", "poke"}, "must be grasp or poke");
  o->tool = tool == 1 ? ToolKind::kPoke : ToolKind::kGrasp;
  // [m] the tool's arc length, in (0, L] (L: the profile's, checked when the rod is built).
  a->Require("tool_s");
  a->Positive("tool_s", &o->tool_s);
  a->Integer("max_iterations", &o->max_iterations, 1, 10000);
  a->Positive("gradient_tolerance", &o->gradient_tolerance);
  a->Positive("step_tolerance", &o->step_tolerance);
  // [s] 0: no budget; so is any budget beyond the steady clock's range, infinity included
  // (solve/deadline.h).
  a->Number("time_budget", &o->time_budget, 0.0, std::numeric_limits<double>::infinity());
  a->Positive("time_step", &o->time_step);  // [s]
  a->Positive("max_tool_move", &o->max_tool_move);
  a->Check(o->max_tool_move <= 1.0, "max_tool_move", "must be <= 1");
  a->Integer("dynamic_newton_iterations", &o->dynamic_newton_iterations, 1, 10000);
  a->Integer("mesh_ring_vertices", &o->mesh_ring_vertices, 3, kMaxMeshRingVertices);
  a->Positive("max_strain", &o->max_strain);
  a->Check(o->max_strain <= 1.0, "max_strain", "must be <= 1");
  a->Bool("hold_orientation", &o->hold_orientation);
  a->Check(!o->hold_orientation || (o->tool == ToolKind::kGrasp &&
                                    o->mode == RuntimeMode::kQuasiStatic),
           "hold_orientation", "is for a quasi-static grasp only");
}

bool RuntimeOptions::Check(std::string* why) const {
  RuntimeOptions values = *this;
  SettingsCheck check;
  Serialize(&check, &values);
  if (check.ok()) return true;
  *why = check.why();
  return false;
}

}  // namespace rodfit
