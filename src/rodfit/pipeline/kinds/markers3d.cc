// Observation kind `markers3d` (docs/formats.md, "Observation entries"): 3-D markers at known arc
// lengths, file `s,x,y,z` [m]; in a moving scene a sequence `t,s,x,y,z` (or `frame,...`).
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/pipeline/sequence_files.h"
#include "rodfit/synth/synth_entry.h"

namespace rodfit {
namespace {

void Keys(EntryKeys* k, ObservationSpec* o) {
  k->Path("file", &o->file, true);
  k->Positive("sigma", &o->sigma, true);  // [m]
  k->Exclusive("s", "count");
  k->ArcLengths("s", &o->s);                       // synth: the markers' arc lengths
  k->Integer("count", &o->count, 1, kMaxSamples);  // synth: markers evenly spaced
  if (k->moving()) {
    k->Positive("frame_rate", &o->frame_rate, false);
    k->Fraction("drop", &o->drop);
  } else {
    k->Fraction("outliers", &o->outliers);
  }
}

#ifndef RODFIT_ENTRY_FORMATS_ONLY  // what the kind does (observation_kind.h)

std::shared_ptr<const Measurement> Markers(const KindContext& c, std::vector<Marker3d> markers) {
  return std::make_shared<ShapeMeasurement<Markers3dObservation>>(
      c.spec().type, c.label(),
      Markers3dObservation(c.vertex_arc_length(), std::move(markers), c.spec().sigma));
}

void Build(const KindContext& c, FitCase* fit_case, std::vector<FitCase>*) {
  const ObservationSpec& spec = c.spec();
  const double L = c.rod_length();
  const CsvTable t = CsvTable::Read(spec.file);
  const auto s = t.Column("s"), x = t.Column("x"), y = t.Column("y"), z = t.Column("z");
  std::vector<Marker3d> markers;
  std::vector<Eigen::Vector3d> positions;
  for (int r = 0; r < t.num_rows(); ++r) {
    CheckArcLength(t, r, s[r], L);
    markers.push_back({std::min(std::max(s[r], 0.0), L), Vec3(x[r], y[r], z[r])});
    positions.emplace_back(x[r], y[r], z[r]);
  }
  if (markers.empty()) throw InputError(spec.file, 0, "", "no rows");
  CheckPointsOnRod(t, "the markers", positions, c.load_case().clamp.position, L);
  fit_case->measurements.push_back(Markers(c, std::move(markers)));
}

std::shared_ptr<const Measurement> Frame(const KindContext& c, bool,
                                         const std::vector<const SequenceSample*>& seen) {
  std::vector<Marker3d> markers;
  for (const SequenceSample* q : seen) markers.push_back({q->s, q->value});
  return Markers(c, std::move(markers));
}

ObservationSequence BuildSequence(const KindContext& c) {
  return ReadShapeSequence(c, /*pixels=*/false, SColumn::kRequired, Frame);
}

#endif  // RODFIT_ENTRY_FORMATS_ONLY

}  // namespace

RODFIT_OBSERVATION_KIND(kMarkers3d,
                        (EntryFormat{
                            "markers3d",
                            "3-D markers at known arc lengths: s,x,y,z [m] (a sequence: t,s,x,y,z)",
                            Keys, /*may_move=*/true}),
                        Build, BuildSequence, SynthMarkers3d, SynthMarkers3dSequence,
                        ReportView::kMarkers3d);

}  // namespace rodfit
