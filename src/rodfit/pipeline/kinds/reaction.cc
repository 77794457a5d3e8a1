// Observation kind `reaction` (docs/formats.md, "Observation entries"): readings of the force
// [N], and at a clamp optionally the moment [N m], the rod exerts on one of the case's held
// points, file `fx,fy,fz[,mx,my,mz]`; in a moving scene a load cell's log `t,fx,...` (or
// `frame,...`).
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/pipeline/sequence_files.h"
#include "rodfit/synth/synth_entry.h"

namespace rodfit {
namespace {

void Keys(EntryKeys* k, ObservationSpec* o) {
  k->Path("file", &o->file, true);
  k->Positive("sigma", &o->sigma, true);  // [N]
  k->HeldPoint("point", &o->point, true);
  k->Positive("sigma_moment", &o->sigma_moment, false);  // [N m], with moment columns
  k->Check(o->sigma_moment == 0.0 || o->point == "clamp" || o->point == "end_clamp", "sigma_moment",
           "a moment is measured only at a clamp (clamp or end_clamp), not at " + o->point);
  if (k->moving()) {
    // Over time a log's readings are its rows (synth: every written frame, or frame_rate).
    k->Positive("frame_rate", &o->frame_rate, false);
    k->Fraction("drop", &o->drop);
  } else {
    k->Integer("count", &o->count, 1, kMaxSamples);  // synth: readings
  }
}

#ifndef RODFIT_ENTRY_FORMATS_ONLY  // what the kind does (observation_kind.h)

void Build(const KindContext& c, FitCase* fit_case, std::vector<FitCase>*) {
  const ObservationSpec& spec = c.spec();
  const CsvTable t = CsvTable::Read(spec.file);
  const auto fx = t.Column("fx"), fy = t.Column("fy"), fz = t.Column("fz");
  const bool moments = t.HasColumn("mx") || t.HasColumn("my") || t.HasColumn("mz");
  if (moments && !(spec.sigma_moment > 0))
    throw InputError(spec.file, 0, "mx", "moment columns need sigma_moment in the entry");
  std::vector<double> mx, my, mz;
  if (moments) mx = t.Column("mx"), my = t.Column("my"), mz = t.Column("mz");
  if (t.num_rows() == 0) throw InputError(spec.file, 0, "", "no rows");
  std::vector<ForceMeasurement> readings;
  for (int r = 0; r < t.num_rows(); ++r) {
    ForceMeasurement f;
    f.force = Vec3(fx[r], fy[r], fz[r]);
    f.sigma = spec.sigma;
    f.point = spec.point;
    f.label = c.label() + " row " + std::to_string(r + 1);
    if (moments) {
      f.moment = Vec3(mx[r], my[r], mz[r]);
      f.sigma_moment = spec.sigma_moment;
    }
    readings.push_back(f);
  }
  fit_case->measurements.push_back(
      std::make_shared<ForceReadings>(spec.type, c.label(), std::move(readings)));
}

#endif  // RODFIT_ENTRY_FORMATS_ONLY

}  // namespace

RODFIT_OBSERVATION_KIND(
    kReaction,
    (EntryFormat{"reaction",
                 "readings of the force (and moment) on a held point: fx,fy,fz[,mx,my,mz] [N, N m]",
                 Keys, /*may_move=*/true}),
    Build, ReadReactionSequence, SynthReaction, SynthReactionSequence, ReportView::kReaction);

}  // namespace rodfit
