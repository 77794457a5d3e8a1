// Observation kind `images` (docs/formats.md, "Observation entries"): a camera image of the
// thread, reduced to `image_points` without s by segmentation, thinning and ordering
// (pipeline/image_observations.h) inside the entry's `roi` and `mask`.
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/kind_support.h"
#ifndef RODFIT_ENTRY_FORMATS_ONLY  // the extraction and the renderer: OpenCV's
#include "rodfit/pipeline/image_observations.h"
#include "rodfit/synth/synth_entry.h"
#endif

namespace rodfit {
namespace {

void Keys(EntryKeys* k, ObservationSpec* o) {
  k->Path("file", &o->file, true);
  k->Positive("sigma", &o->sigma, true);  // [px]
  k->Path("camera", &o->camera, true);
  k->Integer("camera_index", &o->camera_index, 1, 2);
  k->Number("blur", &o->blur, 0.0, kMaxBlurPx);       // synth: Gaussian blur [px]
  k->Number("noise", &o->noise, 0.0, kMaxNoiseGrey);  // synth: pixel noise [grey levels]
  k->Roi("roi", &o->roi);
  k->Path("mask", &o->mask, false);
}

#ifndef RODFIT_ENTRY_FORMATS_ONLY  // what the kind does (observation_kind.h)

void Build(const KindContext& c, FitCase* fit_case, std::vector<FitCase>*) {
  const Camera& camera = c.camera();
  std::vector<Eigen::Vector2d> pixels = ImagePointsFromImage(c.spec(), camera, c.load_case());
  fit_case->measurements.push_back(std::make_shared<ShapeMeasurement<ImageCurveObservation>>(
      c.spec().type, c.label(),
      ImageCurveObservation(c.num_vertices(), camera, std::move(pixels), c.spec().sigma)));
}

#endif  // RODFIT_ENTRY_FORMATS_ONLY

}  // namespace

RODFIT_OBSERVATION_KIND(
    kImages,
    (EntryFormat{
        "images",
        "a camera image of the thread (PNG, JPEG, TIFF, BMP), reduced to its centre-line's pixels",
        Keys, /*may_move=*/false}),
    Build, nullptr, SynthImage, nullptr, ReportView::kImage);

}  // namespace rodfit
