// Observation kind `image_points` (docs/formats.md, "Observation entries"): pixels of a
// calibrated camera, file `s,u,v` (markers at arc length s) or `u,v` (samples of the thread's
// image, each compared with its closest point on the projected centre-line) [px]; in a moving
// scene a sequence `t,s,u,v` or `t,u,v` (or `frame,...`).
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/pipeline/sequence_files.h"
#include "rodfit/synth/synth_entry.h"

namespace rodfit {
namespace {

void Keys(EntryKeys* k, ObservationSpec* o) {
  k->Path("file", &o->file, true);
  k->Positive("sigma", &o->sigma, true);  // [px]
  k->Path("camera", &o->camera, true);
  k->Integer("camera_index", &o->camera_index, 1, 2);  // of a stereo file
  k->Exclusive("s", "count");
  k->ArcLengths("s", &o->s);
  k->Integer("count", &o->count, 1, kMaxSamples);
  if (k->moving()) {
    k->Positive("frame_rate", &o->frame_rate, false);
    k->Fraction("drop", &o->drop);
  } else {
    k->Fraction("outliers", &o->outliers);
  }
}

#ifndef RODFIT_ENTRY_FORMATS_ONLY  // what the kind does (observation_kind.h)

std::shared_ptr<const Measurement> Markers(const KindContext& c, std::vector<MarkerPixel> markers) {
  return std::make_shared<ShapeMeasurement<ImageMarkersObservation>>(
      c.spec().type, c.label(),
      ImageMarkersObservation(c.vertex_arc_length(), c.camera(), std::move(markers),
                              c.spec().sigma));
}

std::shared_ptr<const Measurement> Curve(const KindContext& c,
                                         std::vector<Eigen::Vector2d> pixels) {
  return std::make_shared<ShapeMeasurement<ImageCurveObservation>>(
      c.spec().type, c.label(),
      ImageCurveObservation(c.num_vertices(), c.camera(), std::move(pixels), c.spec().sigma));
}

void Build(const KindContext& c, FitCase* fit_case, std::vector<FitCase>*) {
  const ObservationSpec& spec = c.spec();
  const double L = c.rod_length();
  const CsvTable t = CsvTable::Read(spec.file);
  const Camera& camera = c.camera();
  const auto u = t.Column("u"), v = t.Column("v");
  if (t.num_rows() == 0) throw InputError(spec.file, 0, "", "no rows");
  if (t.HasColumn("s")) {
    const auto s = t.Column("s");
    std::vector<MarkerPixel> markers;
    for (int r = 0; r < t.num_rows(); ++r) {
      CheckArcLength(t, r, s[r], L);
      CheckOnSensor(t, r, Eigen::Vector2d(u[r], v[r]), camera, spec.camera);
      markers.push_back({std::min(std::max(s[r], 0.0), L), Eigen::Vector2d(u[r], v[r])});
    }
    fit_case->measurements.push_back(Markers(c, std::move(markers)));
  } else {
    std::vector<Eigen::Vector2d> pixels;
    for (int r = 0; r < t.num_rows(); ++r) {
      pixels.emplace_back(u[r], v[r]);
      CheckOnSensor(t, r, pixels.back(), camera, spec.camera);
    }
    fit_case->measurements.push_back(Curve(c, std::move(pixels)));
  }
}

std::shared_ptr<const Measurement> Frame(const KindContext& c, bool with_s,
                                         const std::vector<const SequenceSample*>& seen) {
  if (with_s) {
    std::vector<MarkerPixel> markers;
    for (const SequenceSample* q : seen) markers.push_back({q->s, q->value.head<2>()});
    return Markers(c, std::move(markers));
  }
  std::vector<Eigen::Vector2d> pixels;
  for (const SequenceSample* q : seen) pixels.push_back(q->value.head<2>());
  return Curve(c, std::move(pixels));
}

ObservationSequence BuildSequence(const KindContext& c) {
  return ReadShapeSequence(c, /*pixels=*/true, SColumn::kOptional, Frame);
}

#endif  // RODFIT_ENTRY_FORMATS_ONLY

}  // namespace

RODFIT_OBSERVATION_KIND(
    kImagePoints,
    (EntryFormat{"image_points",
                 "pixels of a calibrated camera: s,u,v (markers) or u,v (the thread's image) [px]",
                 Keys, /*may_move=*/true}),
    Build, BuildSequence, SynthImagePoints, SynthImagePointsSequence, ReportView::kPixels);

}  // namespace rodfit
