// Observation kind `points3d` (docs/formats.md, "Observation entries"): unordered 3-D centre-line
// samples, file `x,y,z` [m], each compared with its closest point on the model's centre-line; in
// a moving scene a sequence `t,x,y,z` (or `frame,...`).
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/pipeline/sequence_files.h"
#include "rodfit/synth/synth_entry.h"

namespace rodfit {
namespace {

void Keys(EntryKeys* k, ObservationSpec* o) {
  k->Path("file", &o->file, true);
  k->Positive("sigma", &o->sigma, true);           // [m]
  k->Integer("count", &o->count, 1, kMaxSamples);  // synth: samples
  if (k->moving()) {
    k->Positive("frame_rate", &o->frame_rate, false);
    k->Fraction("drop", &o->drop);
  } else {
    k->Fraction("outliers", &o->outliers);
  }
}

#ifndef RODFIT_ENTRY_FORMATS_ONLY  // what the kind does (observation_kind.h)

std::shared_ptr<const Measurement> Points(const KindContext& c,
                                          std::vector<Eigen::Vector3d> points) {
  return std::make_shared<ShapeMeasurement<Points3dObservation>>(
      c.spec().type, c.label(),
      Points3dObservation(c.num_vertices(), std::move(points), c.spec().sigma));
}

void Build(const KindContext& c, FitCase* fit_case, std::vector<FitCase>*) {
  const ObservationSpec& spec = c.spec();
  const CsvTable t = CsvTable::Read(spec.file);
  const auto x = t.Column("x"), y = t.Column("y"), z = t.Column("z");
  std::vector<Eigen::Vector3d> points;
  for (int r = 0; r < t.num_rows(); ++r) points.emplace_back(x[r], y[r], z[r]);
  if (points.empty()) throw InputError(spec.file, 0, "", "no rows");
  CheckPointsOnRod(t, "the points", points, c.load_case().clamp.position, c.rod_length());
  fit_case->measurements.push_back(Points(c, std::move(points)));
}

std::shared_ptr<const Measurement> Frame(const KindContext& c, bool,
                                         const std::vector<const SequenceSample*>& seen) {
  std::vector<Eigen::Vector3d> points;
  for (const SequenceSample* q : seen) points.push_back(q->value);
  return Points(c, std::move(points));
}

ObservationSequence BuildSequence(const KindContext& c) {
  return ReadShapeSequence(c, /*pixels=*/false, SColumn::kNone, Frame);
}

#endif  // RODFIT_ENTRY_FORMATS_ONLY

}  // namespace

RODFIT_OBSERVATION_KIND(
    kPoints3d,
    (EntryFormat{"points3d", "unordered 3-D centre-line samples: x,y,z [m] (a sequence: t,x,y,z)",
                 Keys, /*may_move=*/true}),
    Build, BuildSequence, SynthPoints3d, SynthPoints3dSequence, ReportView::kPoints3d);

}  // namespace rodfit
