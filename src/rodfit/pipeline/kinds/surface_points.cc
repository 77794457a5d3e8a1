// Observation kind `surface_points` (docs/formats.md, "Observation entries"): points tracked on
// the tissue surface around a poke, in the poked section's plane, file `x,y,z` [m], each compared
// with its closest point on the deformed section ring (fit/measurement.h, SurfacePointSet).
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/synth/synth_entry.h"

namespace rodfit {
namespace {

void Keys(EntryKeys* k, ObservationSpec* o) {
  k->Check(k->load_case().poke.has_value(), "type",
           "surface_points are tracked around a poke, but this case has no poke (add poke: "
           "{s, force} to the case)");
  k->Path("file", &o->file, true);
  k->Positive("sigma", &o->sigma, true);           // [m]
  k->Integer("count", &o->count, 1, kMaxSamples);  // synth: points (default the section's nodes)
}

#ifndef RODFIT_ENTRY_FORMATS_ONLY  // what the kind does (observation_kind.h)

void Build(const KindContext& c, FitCase* fit_case, std::vector<FitCase>*) {
  const ObservationSpec& spec = c.spec();
  const CsvTable t = CsvTable::Read(spec.file);
  const auto x = t.Column("x"), y = t.Column("y"), z = t.Column("z");
  std::vector<Eigen::Vector3d> points;
  for (int r = 0; r < t.num_rows(); ++r) {
    points.emplace_back(x[r], y[r], z[r]);
    CheckReach(t, r, points.back(), c.load_case().clamp.position, c.rod_length());
  }
  if (points.empty()) throw InputError(spec.file, 0, "", "no rows");
  fit_case->measurements.push_back(
      std::make_shared<SurfacePointSet>(spec.type, c.label(), std::move(points), spec.sigma));
}

#endif  // RODFIT_ENTRY_FORMATS_ONLY

}  // namespace

RODFIT_OBSERVATION_KIND(
    kSurfacePoints,
    (EntryFormat{
        "surface_points",
        "points on the tissue surface around a poke, in the poked section's plane: x,y,z [m]", Keys,
        /*may_move=*/false}),
    Build, nullptr, SynthSurfacePoints, nullptr, ReportView::kSurface);

}  // namespace rodfit
