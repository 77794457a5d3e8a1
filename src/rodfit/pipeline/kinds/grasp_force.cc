// Observation kind `grasp_force` (docs/formats.md, "Observation entries"; "Haptic logs as
// recorded"): a haptic instrument's log `t,tool_x,tool_y,tool_z,fx,fy,fz` of the force on the
// instrument holding the rod at arc length s. Each quasi-static sample (the tool at rest) is a
// case of its own: the rod grasped at s where the tool is, its reaction against the force read.
#include <algorithm>

#include "rodfit/io/errors.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/synth/synth_entry.h"

namespace rodfit {
namespace {

void Keys(EntryKeys* k, ObservationSpec* o) {
  k->Path("file", &o->file, true);
  k->Positive("sigma", &o->sigma, true);             // [N]
  k->GraspArcLength("s", &o->s);                     // the grasped point
  k->Integer("count", &o->count, 1, kMaxDragSteps);  // fit: samples used; synth: drag steps
  k->Positive("max_speed", &o->max_speed, false);    // [m/s] a tool slower is at rest
  // How the device logs (docs/formats.md, "Haptic logs as recorded").
  k->Choice("unit", &o->position_scale, {{"m", 1.0}, {"mm", 1e-3}}, "must be m or mm");
  k->Choice("force_unit", &o->force_scale, {{"N", 1.0}, {"mN", 1e-3}}, "must be N or mN");
  k->Frame("device_frame", &o->device_rotation, &o->device_translation);
  k->Choice("force_on", &o->force_sign, {{"instrument", 1.0}, {"tissue", -1.0}},
            "must be instrument (the force on the tool) or tissue (the force the tool applies)");
}

#ifndef RODFIT_ENTRY_FORMATS_ONLY  // what the kind does (observation_kind.h)

// A haptic log (t, tool position, force on the instrument): the samples where the tool is at
// rest, i.e. its speed (central differences) is below max_speed, thinned evenly to `count`.
struct HapticSample {
  double t;
  Vec3 tool, force;
};

std::vector<HapticSample> QuasiStaticSamples(const ObservationSpec& spec, const Vec3& clamp,
                                             double length) {
  const CsvTable t = CsvTable::Read(spec.file);
  const auto time = t.Column("t"), x = t.Column("tool_x"), y = t.Column("tool_y"),
             z = t.Column("tool_z"), fx = t.Column("fx"), fy = t.Column("fy"), fz = t.Column("fz");
  const int n = t.num_rows();
  if (n < 3) throw InputError(spec.file, 0, "", "a force log needs at least 3 samples");
  // The device's units, frame and sign convention (the entry's unit, force_unit, device_frame,
  // force_on) to the scene's.
  std::vector<Vec3> tool(n), force(n);
  for (int r = 0; r < n; ++r) {
    tool[r] = spec.device_rotation * (spec.position_scale * Vec3(x[r], y[r], z[r])) +
              spec.device_translation;
    force[r] =
        spec.force_sign * (spec.device_rotation * (spec.force_scale * Vec3(fx[r], fy[r], fz[r])));
  }
  // The instrument holds the rod: a tool position out of its reach is bad data (each quasi-static
  // sample becomes a held point the solve would chase).
  for (int r = 0; r < n; ++r) CheckReach(t, r, tool[r], clamp, length, "tool_x");
  for (int r = 1; r < n; ++r)
    if (!(time[r] > time[r - 1]))
      throw InputError(spec.file, t.line(r), "t",
                       "time must increase strictly (" + FormatDouble(time[r]) + " after " +
                           FormatDouble(time[r - 1]) + ")");
  std::vector<HapticSample> still;
  for (int r = 0; r < n; ++r) {
    const int a = std::max(0, r - 1), b = std::min(n - 1, r + 1);
    const double speed = (tool[b] - tool[a]).norm() / (time[b] - time[a]);  // [m/s]
    if (speed < spec.max_speed) still.push_back({time[r], tool[r], force[r]});
  }
  if (spec.count == 0 && static_cast<int>(still.size()) > kMaxDragSteps)
    throw InputError(spec.file, 0, "",
                     std::to_string(still.size()) +
                         " quasi-static samples, each a case of the "
                         "fit: more than " +
                         std::to_string(kMaxDragSteps) +
                         " (the limit); give the entry a count to thin them");
  if (still.empty())
    throw InputError(spec.file, 0, "max_speed",
                     "no quasi-static sample: the tool never moves slower than " +
                         FormatDouble(spec.max_speed) + " m/s");
  if (spec.count > 0 && static_cast<int>(still.size()) > spec.count) {
    std::vector<HapticSample> thinned;
    for (int k = 0; k < spec.count; ++k)
      thinned.push_back(still[(k * (still.size() - 1)) / std::max(1, spec.count - 1)]);
    still = thinned;
  }
  return still;
}

void Build(const KindContext& c, FitCase*, std::vector<FitCase>* more_cases) {
  const ObservationSpec& spec = c.spec();
  const LoadCase& load_case = c.experiment().scene.cases[c.case_index()];
  for (const HapticSample& h : QuasiStaticSamples(spec, load_case.clamp.position, c.rod_length())) {
    FitCase gc;
    gc.load_case = load_case;
    gc.load_case.name += "@t=" + FormatDouble(h.t);
    gc.load_case.grasp = Grasp{spec.s.at(0), h.tool};
    ForceMeasurement f;
    f.force = h.force;
    f.sigma = spec.sigma;
    f.label = c.label() + " t=" + FormatDouble(h.t);
    f.time = h.t;
    gc.measurements.push_back(
        std::make_shared<ForceReadings>(spec.type, c.label(), std::vector<ForceMeasurement>{f}));
    more_cases->push_back(std::move(gc));
  }
}

#endif  // RODFIT_ENTRY_FORMATS_ONLY

}  // namespace

RODFIT_OBSERVATION_KIND(
    kGraspForce,
    (EntryFormat{
        "grasp_force",
        "a haptic log of the instrument holding the rod at s: t,tool_x,tool_y,tool_z,fx,fy,fz",
        Keys, /*may_move=*/false}),
    Build, nullptr, SynthGraspForce, nullptr, ReportView::kHapticLog);

}  // namespace rodfit
