// Synthetic observations of an experiment (see synth.h): solve, sample, perturb, render, and
// gather every output file in memory before anything is written, so a failure leaves nothing.
#include "rodfit/synth/synth_entry.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/model/rod.h"
#include "rodfit/observe/camera.h"
#include "rodfit/solve/case_dynamics.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/version.h"
#include "rodfit/vision/camera_file.h"
#include "rodfit/vision/image_codec.h"
#include "rodfit/vision/render.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;


}  // namespace

Random::Random(std::uint32_t seed, const std::string& key) {
  // FNV-1a of the key, so an entry's stream depends on what it is, not where it is.
  std::uint64_t h = 14695981039346656037ull;
  for (const unsigned char c : key) {
    h ^= c;
    h *= 1099511628211ull;
  }
  std::seed_seq seq{seed, static_cast<std::uint32_t>(h), static_cast<std::uint32_t>(h >> 32)};
  engine_.seed(seq);
}

double Random::Uniform() {
  const double hi = static_cast<double>(engine_() >> 5);  // 27 bits
  const double lo = static_cast<double>(engine_() >> 6);  // 26 bits
  return (hi * 67108864.0 + lo) * (1.0 / 9007199254740992.0);
}

double Random::Normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  for (;;) {  // accepts with probability pi / 4
    const double u = 2.0 * Uniform() - 1.0;
    const double v = 2.0 * Uniform() - 1.0;
    const double r2 = u * u + v * v;
    if (r2 > 0.0 && r2 < 1.0) {
      const double f = std::sqrt(-2.0 * std::log(r2) / r2);
      spare_ = v * f;
      has_spare_ = true;
      return u * f;
    }
  }
}

std::uint32_t Random::Index(std::uint32_t n) {
  const std::uint64_t range = std::uint64_t{1} << 32;
  const std::uint64_t limit = range - range % n;
  for (;;) {
    const std::uint64_t r = engine_();
    if (r < limit) return static_cast<std::uint32_t>(r % n);
  }
}

namespace {

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

std::vector<int> ChooseOutliers(double fraction, int n, Random* random) {
  const int k = static_cast<int>(std::lround(fraction * n));
  std::vector<int> order(n);
  for (int i = 0; i < n; ++i) order[i] = i;
  for (int i = 0; i < k; ++i) {
    const int j = i + static_cast<int>(random->Index(static_cast<std::uint32_t>(n - i)));
    std::swap(order[i], order[j]);
  }
  std::vector<int> chosen(order.begin(), order.begin() + k);
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

std::vector<double> MarkerArcLengths(const ObservationSpec& spec, const RodSpec& rod) {
  if (!spec.s.empty()) return spec.s;
  const int count = spec.count > 0 ? spec.count : rod.segments;
  std::vector<double> s(count);
  for (int k = 0; k < count; ++k) s[k] = rod.length * (k + 1) / count;
  return s;
}

namespace {

// Positions t_k of `count` samples evenly spaced over [0, total], both ends included (one sample:
// the middle); default one per vertex.
std::vector<double> EvenlySpaced(int count, double total) {
  std::vector<double> t(count);
  for (int k = 0; k < count; ++k) t[k] = count == 1 ? 0.5 * total : total * k / (count - 1);
  return t;
}

// Positions t_k = (k + 1/2) total / count: the middles of `count` equal parts of [0, total]. A
// sequence's closest-point samples sit there: with the default count, one per edge, none lies on
// a vertex or an end, where its foot would be that vertex and its residual would carry the noise
// along the curve too (more than Observation::num_noise_residuals counts).
std::vector<double> MiddlesOfParts(int count, double total) {
  std::vector<double> t(count);
  for (int k = 0; k < count; ++k) t[k] = total * (k + 0.5) / count;
  return t;
}

// The point at 2-D arc length t along a polyline with cumulative lengths `cum`.
Eigen::Vector2d AlongPolyline(const std::vector<Eigen::Vector2d>& p, const std::vector<double>& cum,
                              double t) {
  const auto it = std::upper_bound(cum.begin(), cum.end(), t);
  const int i = std::clamp(static_cast<int>(it - cum.begin()) - 1, 0, static_cast<int>(p.size()) - 2);
  const double len = cum[i + 1] - cum[i];
  const double f = len > 0.0 ? std::clamp((t - cum[i]) / len, 0.0, 1.0) : 0.0;
  return p[i] + f * (p[i + 1] - p[i]);
}

// Projects every vertex; a vertex at or behind the camera is an error (the rod would cross the
// camera's focal plane, which no lab set-up shows). `depth` gets each vertex's camera z [m].
std::vector<Eigen::Vector2d> ProjectVertices(const SynthEntry& ctx, std::vector<double>* depth) {
  const Camera& camera = *ctx.camera;
  std::vector<Eigen::Vector2d> uv(ctx.shape->x.cols());
  int behind = 0;
  for (int i = 0; i < ctx.shape->x.cols(); ++i) {
    const Eigen::Vector3d p = ctx.shape->x.col(i);
    if (depth) depth->push_back((camera.cam_from_world_R * p + camera.cam_from_world_t).z());
    if (!Project(camera, p, &uv[i])) ++behind;
  }
  if (behind == static_cast<int>(uv.size())) {
    ctx.Fail("camera " + ctx.camera_label + " sees nothing of the rod in case " + ctx.CaseName() +
             " (the rod is behind it)");
  }
  if (behind > 0) {
    ctx.Fail("camera " + ctx.camera_label + ": " + std::to_string(behind) +
             " vertices of the rod in case " + ctx.CaseName() + " are behind the camera");
  }
  return uv;
}

}  // namespace

std::string Summary(const SynthEntry& ctx, int n, int outliers, int dropped) {
  std::string line = "case " + ctx.shape->name + ": " + ctx.file + ": " + ctx.spec->type + ", " +
                     std::to_string(n) + " samples";
  if (outliers > 0) line += ", " + std::to_string(outliers) + " outliers";
  if (dropped > 0) line += ", " + std::to_string(dropped) + " outside the image dropped";
  return line;
}

// The bounding box of the solved vertices grown by margin * L on every side.
void OutlierBox(const SynthEntry& ctx, Eigen::Vector3d* lo, Eigen::Vector3d* hi) {
  const double margin = ctx.options->outlier_box_margin * ctx.experiment->scene.rod.length;
  *lo = ctx.shape->x.rowwise().minCoeff().array() - margin;
  *hi = ctx.shape->x.rowwise().maxCoeff().array() + margin;
}

namespace {

// markers3d at MarkerArcLengths, or points3d at `count` arc lengths evenly spaced over [0, L].
std::string Synth3d(const SynthEntry& ctx, bool markers, std::string* report) {
  const RodSpec& rod = ctx.experiment->scene.rod;
  std::vector<double> s;
  if (markers) {
    s = MarkerArcLengths(*ctx.spec, rod);
  } else {
    s = EvenlySpaced(ctx.spec->count > 0 ? ctx.spec->count : rod.segments + 1, rod.length);
  }
  std::vector<Eigen::Vector3d> p(s.size());
  for (size_t k = 0; k < s.size(); ++k) p[k] = PointAtArcLength(*ctx.shape, s[k]);
  Eigen::Vector3d lo, hi;
  OutlierBox(ctx, &lo, &hi);
  AddNoise(ctx, &p);
  const int outliers = ReplaceOutliers(ctx, lo, hi, &p);
  *report = Summary(ctx, static_cast<int>(p.size()), outliers, 0);
  return markers ? FormatMarkersCsv(s, p) : FormatPoints3dCsv(p);
}

}  // namespace

std::string SynthMarkers3d(const SynthEntry& entry, std::string* report) {
  return Synth3d(entry, /*markers=*/true, report);
}

std::string SynthPoints3d(const SynthEntry& entry, std::string* report) {
  return Synth3d(entry, /*markers=*/false, report);
}

namespace {

std::string Show(double v);

// The sample times of a sequence: every 1 / frame_rate, or every written frame of the
// dynamics (output_every steps), from 0 to dynamics.duration. More times than a file may hold
// rows is the entry's error, found before they are listed (a frame_rate of 1e12 Hz would ask for
// 1e10 of them, and 1e308 Hz for more than a long counts).
std::vector<double> SequenceTimes(const SynthEntry& ctx) {
  const ObservationSpec& spec = *ctx.spec;
  const DynamicsSpec& dynamics = *ctx.experiment->scene.dynamics;
  const double interval =
      spec.frame_rate > 0.0 ? 1.0 / spec.frame_rate : dynamics.time_step * dynamics.output_every;
  // Round-off of the ratio must not lose the last frame.
  const double last = std::floor(dynamics.duration / interval * (1.0 + 1e-12));
  if (!(last < static_cast<double>(kMaxCsvRows)))
    ctx.Fail(Show(last + 1.0) +
             (spec.frame_rate > 0.0
                  ? " sample times (dynamics.duration x frame_rate), above the limit of " +
                        std::to_string(kMaxCsvRows) + " rows (lower frame_rate)"
                  : " sample times (every written step of the dynamics), above the limit of " +
                        std::to_string(kMaxCsvRows) + " rows (give frame_rate, or raise "
                        "dynamics.output_every)"));
  const long frames = static_cast<long>(last);
  std::vector<double> t;
  for (long k = 0; k <= frames; ++k) t.push_back(k * interval);
  return t;
}

// A markers3d sequence of a moving case (docs/formats.md, "Observation sequences"): the case run
// from its initial state, the markers' positions at every sample time with Gaussian noise of the
// entry's sigma, a fraction `drop` of the samples left empty (not seen). Rows time-major;
// columns frame,s,x,y,z with the entry's frame_rate, else t,s,x,y,z.
}  // namespace

std::string SynthMarkers3dSequence(const SynthEntry& ctx, std::string* report) {
  const std::string& file = ctx.file;
  const Scene& scene = ctx.experiment->scene;
  const std::vector<double> s = MarkerArcLengths(*ctx.spec, scene.rod);
  const std::vector<double> t = SequenceTimes(ctx);
  const size_t n = s.size() * t.size();
  if (n > static_cast<size_t>(kMaxCsvRows))
    ctx.Fail(std::to_string(n) + " samples (markers x times), above the limit of " +
             std::to_string(kMaxCsvRows) + " rows (lower frame_rate or the markers)");
  CaseSamples run;
  try {
    run = SampleCaseDynamics(scene, ctx.case_index, ctx.options->statics, s, t, {});
  } catch (const std::exception& e) {
    ctx.Fail("case " + ctx.CaseName() + ": " + e.what());
  }
  if (!run.ok) ctx.Fail("case " + ctx.CaseName() + " does not run: " + run.reason);
  std::vector<Eigen::Vector3d> p;
  p.reserve(n);
  for (size_t k = 0; k < t.size(); ++k)
    for (size_t m = 0; m < s.size(); ++m) p.push_back(run.x[k].col(m));
  AddNoise(ctx, &p);
  std::vector<char> dropped(n, 0);
  int drops = 0;
  if (ctx.options->add_noise)
    for (const int i : ChooseOutliers(ctx.spec->drop, static_cast<int>(n), ctx.random)) {
      dropped[i] = 1;
      ++drops;
    }
  const bool by_frame = ctx.spec->frame_rate > 0.0;
  std::string out = by_frame ? "frame,s,x,y,z\n" : "t,s,x,y,z\n";
  for (size_t k = 0; k < t.size(); ++k)
    for (size_t m = 0; m < s.size(); ++m) {
      const size_t i = k * s.size() + m;
      out += (by_frame ? std::to_string(k) : FormatDouble(t[k])) + "," + FormatDouble(s[m]);
      out += dropped[i] ? std::string(",,,\n")
                        : "," + FormatDouble(p[i].x()) + "," + FormatDouble(p[i].y()) + "," +
                              FormatDouble(p[i].z()) + "\n";
    }
  *report = "case " + ctx.shape->name + ": " + file + ": markers3d sequence, " +
            std::to_string(s.size()) + " markers x " + std::to_string(t.size()) + " times";
  if (drops > 0) *report += ", " + std::to_string(drops) + " samples dropped";
  return out;
}

namespace {

// The pixels an image_points entry's camera records of the shape ctx.shape: at the entry's `s`
// (markers), else along the projected centre-line `count` points evenly spaced, both ends
// included (default segments + 1), or for a sequence's frame at the middles of `count` equal
// parts (MiddlesOfParts, default segments). Noise is drawn for every sample, visible or not, so
// that the draws do not depend on which samples the camera sees; then samples behind the camera
// or whose true or measured pixel is off the sensor are left out.
struct PixelSamples {
  std::vector<Eigen::Vector2d> uv;  // [px] as measured
  std::vector<double> s;            // [m] per pixel, markers only
  int total = 0;                    // samples before those off the sensor were left out
};

PixelSamples SamplePixels(const SynthEntry& ctx, bool sequence_frame) {
  const Camera& camera = *ctx.camera;
  const bool with_s = !ctx.spec->s.empty();
  std::vector<double> s;
  std::vector<Eigen::Vector2d> uv;
  std::vector<bool> in_front;  // a marker behind the camera is not seen
  if (with_s) {
    s = ctx.spec->s;
    for (const double sk : s) {
      Eigen::Vector2d q = Eigen::Vector2d::Zero();
      in_front.push_back(Project(camera, PointAtArcLength(*ctx.shape, sk), &q));
      uv.push_back(q);
    }
  } else {
    // Evenly spaced along the projected centre-line: what a tracker without arc lengths reports.
    const std::vector<Eigen::Vector2d> vertices = ProjectVertices(ctx, nullptr);
    std::vector<double> cum(vertices.size(), 0.0);
    for (size_t i = 1; i < vertices.size(); ++i) {
      cum[i] = cum[i - 1] + (vertices[i] - vertices[i - 1]).norm();
    }
    const int segments = ctx.experiment->scene.rod.segments;
    const int count =
        ctx.spec->count > 0 ? ctx.spec->count : sequence_frame ? segments : segments + 1;
    for (const double t : sequence_frame ? MiddlesOfParts(count, cum.back())
                                         : EvenlySpaced(count, cum.back())) {
      uv.push_back(AlongPolyline(vertices, cum, t));
    }
    in_front.assign(uv.size(), true);
  }
  PixelSamples out;
  out.total = static_cast<int>(uv.size());
  std::vector<Eigen::Vector2d> measured = uv;
  AddNoise(ctx, &measured);
  for (int k = 0; k < out.total; ++k) {
    if (!in_front[k] || !camera.InImage(uv[k]) || !camera.InImage(measured[k])) continue;
    out.uv.push_back(measured[k]);
    if (with_s) out.s.push_back(s[k]);
  }
  return out;
}

[[noreturn]] void FailSeesNothing(const SynthEntry& ctx) {
  const Camera& camera = *ctx.camera;
  ctx.Fail("camera " + ctx.camera_label + " sees nothing of the rod in case " + ctx.CaseName() +
           " (every sample projects outside its " + std::to_string(camera.K.width) + "x" +
           std::to_string(camera.K.height) + " image)");
}

}  // namespace

std::string SynthImagePoints(const SynthEntry& ctx, std::string* report) {
  const Camera& camera = *ctx.camera;
  PixelSamples samples = SamplePixels(ctx, /*sequence_frame=*/false);
  if (samples.uv.empty()) FailSeesNothing(ctx);
  // Tracking mistakes land anywhere on the sensor.
  const int outliers = ReplaceOutliers(
      ctx, Eigen::Vector2d(-0.5, -0.5),
      Eigen::Vector2d(camera.K.width - 0.5, camera.K.height - 0.5), &samples.uv);
  *report = Summary(ctx, static_cast<int>(samples.uv.size()), outliers,
                    samples.total - static_cast<int>(samples.uv.size()));
  return FormatImagePointsCsv(samples.uv, ctx.spec->s.empty() ? nullptr : &samples.s);
}

namespace {

// A points3d or image_points sequence of a moving case (docs/formats.md, "Observation
// sequences"): the case run from its initial state, and at every sample time (SequenceTimes) the
// samples of the shape then — points3d at the middles of `count` (default segments) equal parts
// of [0, L] in s, image_points as SamplePixels (pixels off the sensor left out) — with Gaussian
// noise of the entry's sigma and a fraction `drop` of the samples written empty (not seen). Rows
// time-major; a frame column with the entry's frame_rate, else t.
std::string SynthShapeSequence(const SynthEntry& ctx, bool pixels, std::string* report) {
  const std::string& file = ctx.file;
  const Scene& scene = ctx.experiment->scene;
  const std::vector<double> t = SequenceTimes(ctx);
  const bool with_s = pixels && !ctx.spec->s.empty();
  const int count = ctx.spec->count > 0 ? ctx.spec->count : scene.rod.segments;
  const std::vector<double> s_points = MiddlesOfParts(count, scene.rod.length);
  const size_t per_frame = with_s ? ctx.spec->s.size() : static_cast<size_t>(count);
  if (per_frame * t.size() > static_cast<size_t>(kMaxCsvRows))
    ctx.Fail(std::to_string(per_frame * t.size()) + " samples (samples x times), above the limit "
             "of " + std::to_string(kMaxCsvRows) + " rows (lower frame_rate or count)");
  CaseShape shape{ctx.shape->name, {}, {}};
  CaseSamples run;
  try {
    // Every vertex, so that the shape at each time is the static entry's.
    shape.s = ctx.vertex_arc_length;
    run = SampleCaseDynamics(scene, ctx.case_index, ctx.options->statics, shape.s, t, {});
  } catch (const std::exception& e) {
    ctx.Fail("case " + ctx.CaseName() + ": " + e.what());
  }
  if (!run.ok) ctx.Fail("case " + ctx.CaseName() + " does not run: " + run.reason);
  // Per frame, its samples' values: x, y, z [m] or u, v [px] (and s for pixel markers).
  std::vector<std::vector<Eigen::Vector3d>> values(t.size());
  std::vector<std::vector<double>> s_of(t.size());
  int total = 0, written = 0;
  for (size_t k = 0; k < t.size(); ++k) {
    shape.x = run.x[k];
    SynthEntry frame = ctx;
    frame.shape = &shape;
    frame.when = " at t = " + FormatDouble(t[k]) + " s";
    if (pixels) {
      const PixelSamples samples = SamplePixels(frame, /*sequence_frame=*/true);
      total += samples.total;
      for (const Eigen::Vector2d& uv : samples.uv) values[k].emplace_back(uv.x(), uv.y(), 0.0);
      s_of[k] = samples.s;
    } else {
      std::vector<Eigen::Vector3d> p;
      for (const double sk : s_points) p.push_back(PointAtArcLength(shape, sk));
      AddNoise(frame, &p);
      total += static_cast<int>(p.size());
      values[k] = std::move(p);
    }
    written += static_cast<int>(values[k].size());
  }
  if (written == 0) FailSeesNothing(ctx);
  std::vector<char> dropped(written, 0);
  int drops = 0;
  if (ctx.options->add_noise)
    for (const int i : ChooseOutliers(ctx.spec->drop, written, ctx.random)) {
      dropped[i] = 1;
      ++drops;
    }
  const bool by_frame = ctx.spec->frame_rate > 0.0;
  std::string out = by_frame ? "frame" : "t";
  out += with_s ? ",s" : "";
  out += pixels ? ",u,v\n" : ",x,y,z\n";
  int i = 0;
  for (size_t k = 0; k < t.size(); ++k)
    for (size_t m = 0; m < values[k].size(); ++m, ++i) {
      out += by_frame ? std::to_string(k) : FormatDouble(t[k]);
      if (with_s) out += "," + FormatDouble(s_of[k][m]);
      const Eigen::Vector3d& v = values[k][m];
      if (dropped[i])
        out += pixels ? ",,\n" : ",,,\n";
      else if (pixels)
        out += "," + FormatDouble(v.x()) + "," + FormatDouble(v.y()) + "\n";
      else
        out += "," + FormatDouble(v.x()) + "," + FormatDouble(v.y()) + "," + FormatDouble(v.z()) +
               "\n";
    }
  *report = "case " + ctx.shape->name + ": " + file + ": " + ctx.spec->type + " sequence, " +
            std::to_string(written) + " samples over " + std::to_string(t.size()) + " times";
  if (drops > 0) *report += ", " + std::to_string(drops) + " samples dropped";
  if (total > written)
    *report += ", " + std::to_string(total - written) + " outside the image left out";
  return out;
}

}  // namespace

std::string SynthPoints3dSequence(const SynthEntry& entry, std::string* report) {
  return SynthShapeSequence(entry, /*pixels=*/false, report);
}

std::string SynthImagePointsSequence(const SynthEntry& entry, std::string* report) {
  return SynthShapeSequence(entry, /*pixels=*/true, report);
}

std::string SynthImage(const SynthEntry& ctx, std::string* report) {
  const std::string& file = ctx.file;
  const Camera& camera = *ctx.camera;
  if (Lower(fs::path(ctx.spec->file).extension().string()) != ".png") {
    ctx.Fail("synth writes images as PNG; name the file *.png, not " + ctx.spec->file);
  }
  std::vector<double> depth;
  const std::vector<Eigen::Vector2d> uv = ProjectVertices(ctx, &depth);
  // The tube's silhouette half-width under a pinhole: focal length times radius over depth.
  const double focal_px = 0.5 * (camera.K.fx + camera.K.fy);
  std::vector<double> half_width(uv.size());
  for (size_t i = 0; i < uv.size(); ++i) {
    half_width[i] = focal_px * ctx.experiment->scene.rod.radius / depth[i];
  }
  // Visible when some point of the tube, sampled at most a pixel apart, touches the sensor.
  bool visible = false;
  for (size_t i = 0; i + 1 < uv.size() && !visible; ++i) {
    const int steps = 1 + static_cast<int>(std::min(1e6, std::ceil((uv[i + 1] - uv[i]).norm())));
    for (int k = 0; k <= steps && !visible; ++k) {
      const double f = static_cast<double>(k) / steps;
      const double w = half_width[i] + f * (half_width[i + 1] - half_width[i]);
      visible = camera.InImage(uv[i] + f * (uv[i + 1] - uv[i]), -(w + 1.0));
    }
  }
  if (!visible) {
    ctx.Fail("camera " + ctx.camera_label + " sees nothing of the rod in case " + ctx.CaseName() +
             " (it projects outside its " + std::to_string(camera.K.width) + "x" +
             std::to_string(camera.K.height) + " image)");
  }
  RenderOptions render;
  render.width = camera.K.width;
  render.height = camera.K.height;
  render.blur_sigma = ctx.spec->blur;
  render.noise_sigma = ctx.options->add_noise ? ctx.spec->noise : 0.0;
  render.rng = &ctx.random->engine();
  cv::Mat image;
  try {
    image = RenderThreadImage(uv, half_width, render);
  } catch (const std::invalid_argument& e) {
    ctx.Fail(std::string("cannot render the image: ") + e.what());
  }
  std::string png, why;
  if (!EncodeImageBytes(ImageFormat::kPng, image, &png, &why)) {
    ctx.Fail("cannot encode the image as PNG: " + why);
  }
  *report = "case " + ctx.shape->name + ": " + file + ": images, " +
            std::to_string(camera.K.width) + "x" + std::to_string(camera.K.height) + " px";
  return png;
}

namespace {

// Solves `load_case` with its grasp moved to `position` from the case's start and returns the
// force on the instrument; *warm becomes this solution.
Eigen::Vector3d ReactionAt(const SynthEntry& ctx, const LoadCase& load_case,
                           const Eigen::Vector3d& position, const std::string& where,
                           std::optional<CaseSolution>* warm) {
  const Scene& scene = ctx.experiment->scene;
  LoadCase moved = load_case;
  moved.grasp = Grasp{ctx.spec->s.at(0), position};
  moved.start = StartShape{};
  try {
    auto model = std::make_shared<const RodModel>(scene.rod, scene.material, scene.gravity, moved,
                                                  scene.springs);
    // Each stop from the case's start, as `simulate` and `fit` solve a grasped case (`warm` only
    // keeps the solution).
    RodState start = StartState(*model, ctx.solution);
    CaseSolution solved = SolveModel(model, scene, nullptr, ctx.options->statics, nullptr, &start);
    if (!solved.ok()) {
      ctx.Fail("case " + ctx.CaseName() + ": the grasp " + where + " does not converge: " +
               solved.summary.reason);
    }
    for (const HeldReaction& r : solved.reactions)
      if (r.point == "grasp") {
        *warm = std::move(solved);
        for (const HeldReaction& q : (*warm)->reactions)
          if (q.point == "grasp") return q.force;
      }
    ctx.Fail("case " + ctx.CaseName() + ": the grasp " + where + " holds no point");
  } catch (const std::invalid_argument& e) {
    ctx.Fail("case " + ctx.CaseName() + ": the grasp " + where + ": " + e.what());
  }
}

// Numbers in messages as a person would type them (not FormatDouble's round-trip digits).
std::string Show(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.10g", v);
  return buffer;
}

std::string FormatPoint(const Eigen::Vector3d& p) {
  return "[" + Show(p.x()) + ", " + Show(p.y()) + ", " + Show(p.z()) + "]";
}

// A haptic log of the instrument dragging the grasped point from its rest position to the
// case's grasp.position in steps, dwelling at each (the schedule is SynthOptions' comment).
}  // namespace

std::string SynthGraspForce(const SynthEntry& ctx, std::string* report) {
  const std::string& file = ctx.file;
  // A log longer than this is a mistake in max_speed or the rate, not a protocol (~100 MB).
  constexpr double kMaxRows = 1e6;
  const Scene& scene = ctx.experiment->scene;
  const SynthOptions& options = *ctx.options;
  const ObservationSpec& spec = *ctx.spec;
  const LoadCase& load_case = scene.cases[ctx.case_index];
  if (!load_case.grasp) {
    ctx.Fail("case " + ctx.CaseName() + " has no grasp: a grasp_force log drags s to the case's "
             "grasp.position (add grasp: {s, position} to the case)");
  }
  const double s = spec.s.at(0);
  if (std::abs(s - load_case.grasp->s) > 1e-9 * scene.rod.length) {
    ctx.Fail("s = " + Show(s) + " is not the case's grasp.s = " + Show(load_case.grasp->s) +
             ": the log must be of the case's grasp");
  }
  const int steps = spec.count > 0 ? spec.count : options.haptic_default_steps;
  const double dt = 1.0 / options.haptic_rate;
  const int dwell = static_cast<int>(std::lround(options.haptic_dwell_time * options.haptic_rate));
  const Eigen::Vector3d start =
      load_case.clamp.position + s * load_case.clamp.tangent.normalized();
  const Eigen::Vector3d end = load_case.grasp->position;
  const double move_speed = options.haptic_move_speed_factor * spec.max_speed;  // [m/s]
  const double intervals_real = std::ceil((end - start).norm() / steps / (move_speed * dt));
  const double rows_real = 1.0 + steps * (std::max(2.0, intervals_real) - 1.0 + dwell);
  if (!(rows_real <= kMaxRows)) {
    ctx.Fail("the log would have " + Show(std::round(rows_real)) + " samples (more than " +
             Show(kMaxRows) + "): raise max_speed or lower count");
  }
  const int intervals = std::max(2, static_cast<int>(intervals_real));

  // The tool's stops P_0..P_N and the forces there.
  std::vector<Eigen::Vector3d> stop(steps + 1), force(steps + 1);
  std::optional<CaseSolution> warm;
  for (int k = 0; k <= steps; ++k) {
    stop[k] = k == steps ? end : Eigen::Vector3d(start + (double(k) / steps) * (end - start));
    force[k] = ReactionAt(ctx, load_case, stop[k],
                          "at step " + std::to_string(k) + " of " + std::to_string(steps) +
                              " (tool at " + FormatPoint(stop[k]) + ")",
                          &warm);
  }

  std::vector<HapticLogRow> rows;
  rows.reserve(static_cast<size_t>(rows_real));
  auto add = [&](const Eigen::Vector3d& tool, const Eigen::Vector3d& f) {
    rows.push_back({static_cast<double>(rows.size()) / options.haptic_rate, tool, f});
  };
  add(stop[0], force[0]);
  for (int k = 1; k <= steps; ++k) {
    for (int j = 1; j < intervals; ++j) {  // the move: not quasi-static, forces interpolated
      const double f = static_cast<double>(j) / intervals;
      add(stop[k - 1] + f * (stop[k] - stop[k - 1]), force[k - 1] + f * (force[k] - force[k - 1]));
    }
    for (int d = 0; d < dwell; ++d) add(stop[k], force[k]);
  }
  if (options.add_noise) {
    const double tool_sigma = options.haptic_tool_noise_factor * spec.max_speed * dt;  // [m]
    for (HapticLogRow& row : rows) {
      for (int d = 0; d < 3; ++d) row.tool(d) += tool_sigma * ctx.random->Normal();
      for (int d = 0; d < 3; ++d) row.force(d) += spec.sigma * ctx.random->Normal();
    }
  }
  // Written as the entry says the device logs (unit, force_unit, device_frame, force_on): the
  // inverse of what the fit applies when it reads the log.
  for (HapticLogRow& row : rows) {
    row.tool = spec.device_rotation.transpose() * (row.tool - spec.device_translation) /
               spec.position_scale;
    row.force = spec.force_sign * (spec.device_rotation.transpose() * row.force) / spec.force_scale;
  }
  char speed[32];
  std::snprintf(speed, sizeof(speed), "%.3g", (end - start).norm() / steps / (intervals * dt));
  *report = "case " + ctx.shape->name + ": " + file + ": grasp_force, " +
            std::to_string(rows.size()) + " samples, " + std::to_string(steps) + " dwells of " +
            std::to_string(dwell) + " at " + Show(options.haptic_rate) +
            " Hz, moves at " + speed + " m/s";
  return FormatHapticLogCsv(rows);
}

// `reaction`: `count` (default 1) readings of the force (and, with sigma_moment, the moment) the
// rod exerts on the entry's held point, with Gaussian noise of sigma and sigma_moment.
std::string SynthReaction(const SynthEntry& ctx, std::string* report) {
  const std::string& file = ctx.file;
  const ObservationSpec& spec = *ctx.spec;
  const HeldReaction* found = nullptr;
  for (const HeldReaction& r : ctx.solution->reactions)
    if (r.point == spec.point) found = &r;
  if (!found) ctx.Fail("case " + ctx.CaseName() + " holds no " + spec.point);
  const bool moment = spec.sigma_moment > 0;
  const int count = spec.count > 0 ? spec.count : 1;
  std::string out = moment ? "fx,fy,fz,mx,my,mz\n" : "fx,fy,fz\n";
  for (int k = 0; k < count; ++k) {
    Eigen::Vector3d f = found->force, m = found->moment;
    if (ctx.options->add_noise) {
      for (int d = 0; d < 3; ++d) f(d) += spec.sigma * ctx.random->Normal();
      if (moment)
        for (int d = 0; d < 3; ++d) m(d) += spec.sigma_moment * ctx.random->Normal();
    }
    out += FormatDouble(f.x()) + "," + FormatDouble(f.y()) + "," + FormatDouble(f.z());
    if (moment) out += "," + FormatDouble(m.x()) + "," + FormatDouble(m.y()) + "," + FormatDouble(m.z());
    out += "\n";
  }
  *report = "case " + ctx.shape->name + ": " + file + ": reaction at " + spec.point + ", " +
            std::to_string(count) + " reading(s)";
  return out;
}

// A `reaction` sequence of a moving case (docs/formats.md, "Observation sequences"): the case
// run from its initial state, the force (and with sigma_moment the moment) the rod exerts on the
// entry's held point at every sample time (MovingReactions) with Gaussian noise of sigma (and
// sigma_moment), a fraction `drop` of the readings written empty (not taken). Columns
// frame,fx,fy,fz[,mx,my,mz] with the entry's frame_rate, else t,....
std::string SynthReactionSequence(const SynthEntry& ctx, std::string* report) {
  const std::string& file = ctx.file;
  const Scene& scene = ctx.experiment->scene;
  const ObservationSpec& spec = *ctx.spec;
  const std::vector<double> t = SequenceTimes(ctx);
  if (t.size() > static_cast<size_t>(kMaxCsvRows))
    ctx.Fail(std::to_string(t.size()) + " readings, above the limit of " +
             std::to_string(kMaxCsvRows) + " rows (lower frame_rate)");
  CaseSamples run;
  try {
    run = SampleCaseDynamics(scene, ctx.case_index, ctx.options->statics, {}, t, {}, true);
  } catch (const std::exception& e) {
    ctx.Fail("case " + ctx.CaseName() + ": " + e.what());
  }
  if (!run.ok) ctx.Fail("case " + ctx.CaseName() + " does not run: " + run.reason);
  const bool moment = spec.sigma_moment > 0;
  std::vector<char> dropped(t.size(), 0);
  int drops = 0;
  if (ctx.options->add_noise)
    for (const int i : ChooseOutliers(spec.drop, static_cast<int>(t.size()), ctx.random)) {
      dropped[i] = 1;
      ++drops;
    }
  const bool by_frame = spec.frame_rate > 0.0;
  std::string out = std::string(by_frame ? "frame" : "t") +
                    (moment ? ",fx,fy,fz,mx,my,mz\n" : ",fx,fy,fz\n");
  for (size_t k = 0; k < t.size(); ++k) {
    const HeldReaction* found = nullptr;
    for (const HeldReaction& r : run.reactions[k])
      if (r.point == spec.point) found = &r;
    if (!found) ctx.Fail("case " + ctx.CaseName() + " holds no " + spec.point);
    // Noise is drawn for every reading, taken or not, so the draws do not depend on the drops.
    Eigen::Vector3d f = found->force, m = found->moment;
    if (ctx.options->add_noise) {
      for (int d = 0; d < 3; ++d) f(d) += spec.sigma * ctx.random->Normal();
      if (moment)
        for (int d = 0; d < 3; ++d) m(d) += spec.sigma_moment * ctx.random->Normal();
    }
    out += by_frame ? std::to_string(k) : FormatDouble(t[k]);
    if (dropped[k]) {
      out += moment ? ",,,,,,\n" : ",,,\n";
      continue;
    }
    out += "," + FormatDouble(f.x()) + "," + FormatDouble(f.y()) + "," + FormatDouble(f.z());
    if (moment) out += "," + FormatDouble(m.x()) + "," + FormatDouble(m.y()) + "," + FormatDouble(m.z());
    out += "\n";
  }
  *report = "case " + ctx.shape->name + ": " + file + ": reaction sequence at " + spec.point +
            ", " + std::to_string(t.size()) + " times";
  if (drops > 0) *report += ", " + std::to_string(drops) + " readings dropped";
  return out;
}

// `surface_points`: the case's poke solved on its equilibrium, and `count` (default the section's
// nodes) points on the deformed ring at angles 2 pi (k + 1/2) / count about the section's centre
// (where the ray from the centre crosses the ring's polygon, in the section's plane), mapped to
// the world; Gaussian noise of sigma on every world coordinate.
std::string SynthSurfacePoints(const SynthEntry& ctx, std::string* report) {
  const Scene& scene = ctx.experiment->scene;
  const LoadCase& load_case = scene.cases[ctx.case_index];
  if (!load_case.poke || !scene.section) {
    ctx.Fail("case " + ctx.CaseName() + " has no poke: surface_points are tracked around one");
  }
  if (!ctx.solution->poke) ctx.Fail("case " + ctx.CaseName() + ": the poke was not solved");
  const PokeResult& poke = *ctx.solution->poke;
  if (!poke.ring.summary.converged) {
    ctx.Fail("case " + ctx.CaseName() + ": the poked ring does not converge: " +
             poke.ring.summary.BriefReport());
  }
  const Eigen::Matrix2Xd& ring = poke.ring.nodes;
  const int n = static_cast<int>(ring.cols());
  const int count = ctx.spec->count > 0 ? ctx.spec->count : n;
  Eigen::Matrix2Xd sample(2, count);
  for (int k = 0; k < count; ++k) {
    const double angle = 2.0 * M_PI * (k + 0.5) / count;
    const Eigen::Vector2d u(std::cos(angle), std::sin(angle));
    // The nearest crossing of the ray {r u, r > 0} with an edge a + t (b - a), t in [0, 1].
    double best = std::numeric_limits<double>::infinity();
    for (int j = 0; j < n; ++j) {
      const Eigen::Vector2d a = ring.col(j), e = ring.col((j + 1) % n) - a;
      const double det = u.x() * (-e.y()) - u.y() * (-e.x());  // [u, -e] (r, t) = a
      if (std::abs(det) < 1e-300) continue;
      const double r = (a.x() * (-e.y()) - a.y() * (-e.x())) / det;
      const double t = (u.x() * a.y() - u.y() * a.x()) / det;
      if (r > 0.0 && t >= 0.0 && t <= 1.0) best = std::min(best, r);
    }
    if (!std::isfinite(best)) ctx.Fail("the deformed ring does not surround its centre");
    sample.col(k) = best * u;
  }
  const Eigen::Matrix3Xd world = SectionToWorld(sample, poke.placement);
  std::vector<Eigen::Vector3d> p(count);
  for (int k = 0; k < count; ++k) p[k] = world.col(k);
  AddNoise(ctx, &p);
  *report = Summary(ctx, count, 0, 0);
  return FormatPoints3dCsv(p);
}

std::vector<CaseSolution> SolveCases(const Experiment& ex, const StaticsOptions& statics) {
  std::vector<CaseSolution> out;
  out.reserve(ex.scene.cases.size());
  for (size_t c = 0; c < ex.scene.cases.size(); ++c) {
    const LoadCase& load_case = ex.scene.cases[c];
    const std::string key = "cases[" + std::to_string(c) + "]";
    const int line = ex.cases[c].line;
    try {
      out.push_back(SolveCase(ex.scene, static_cast<int>(c), out.empty() ? nullptr : &out.back(),
                              statics));
    } catch (const std::invalid_argument& e) {
      throw InputError(ex.path, line, key, "case '" + load_case.name + "': " + e.what());
    }
    if (!out.back().ok()) {
      throw InputError(ex.path, line, key,
                       "case '" + load_case.name + "' does not converge: " + out.back().summary.reason);
    }
  }
  return out;
}

namespace {

std::string Absolute(const std::string& path) {
  std::error_code ec;
  fs::path p = fs::absolute(path.empty() ? fs::path(".") : fs::path(path), ec);
  return p.lexically_normal().string();
}

}  // namespace

bool SynthOptions::Check(std::string* why) const {
  if (!(outlier_box_margin >= 0.0) || !std::isfinite(outlier_box_margin)) {
    if (why) *why = "outlier_box_margin must be finite and >= 0";
    return false;
  }
  auto fail = [why](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  if (!(haptic_rate > 0.0) || !std::isfinite(haptic_rate)) {
    return fail("haptic_rate must be finite and > 0");
  }
  if (!(haptic_dwell_time * haptic_rate >= 2.5) || !std::isfinite(haptic_dwell_time)) {
    // A dwell needs a sample whose neighbours are both still for the central difference.
    return fail("haptic_dwell_time must be finite and hold at least 3 samples");
  }
  if (!(haptic_move_speed_factor > 2.0) || !std::isfinite(haptic_move_speed_factor)) {
    return fail("haptic_move_speed_factor must be finite and > 2");
  }
  if (!(haptic_tool_noise_factor >= 0.0 && haptic_tool_noise_factor <= 0.2)) {
    return fail("haptic_tool_noise_factor must be in [0, 0.2]");
  }
  if (haptic_default_steps < 1) return fail("haptic_default_steps must be >= 1");
  return statics.Check(why);
}

std::string SynthRelativePath(const std::string& path, const std::string& experiment_directory) {
  const fs::path file = Absolute(path);
  const fs::path rel = file.lexically_relative(Absolute(experiment_directory));
  if (!rel.empty() && rel.is_relative() && *rel.begin() != ".." && rel != ".") {
    return rel.generic_string();
  }
  return file.filename().string();
}

Eigen::Vector3d PointAtArcLength(const CaseShape& shape, double s) {
  const int n = static_cast<int>(shape.s.size());
  if (n == 0) throw std::invalid_argument("PointAtArcLength: empty shape");
  if (n == 1 || s <= shape.s.front()) return shape.x.col(0);
  if (s >= shape.s.back()) return shape.x.col(n - 1);
  const int i = static_cast<int>(std::upper_bound(shape.s.begin(), shape.s.end(), s) -
                                 shape.s.begin()) - 1;
  const double f = (s - shape.s[i]) / (shape.s[i + 1] - shape.s[i]);
  // Written so that f = 0 gives the vertex exactly.
  return shape.x.col(i) + f * (shape.x.col(i + 1) - shape.x.col(i));
}

std::string FormatMarkersCsv(const std::vector<double>& s, const std::vector<Eigen::Vector3d>& p) {
  if (s.size() != p.size()) throw std::invalid_argument("FormatMarkersCsv: s.size() != p.size()");
  std::string out = "s,x,y,z\n";
  for (size_t k = 0; k < p.size(); ++k) {
    out += FormatDouble(s[k]) + "," + FormatDouble(p[k].x()) + "," + FormatDouble(p[k].y()) +
           "," + FormatDouble(p[k].z()) + "\n";
  }
  return out;
}

std::string FormatHapticLogCsv(const std::vector<HapticLogRow>& rows) {
  std::string out = "t,tool_x,tool_y,tool_z,fx,fy,fz\n";
  for (const HapticLogRow& r : rows) {
    out += FormatDouble(r.t);
    for (int d = 0; d < 3; ++d) out += "," + FormatDouble(r.tool(d));
    for (int d = 0; d < 3; ++d) out += "," + FormatDouble(r.force(d));
    out += "\n";
  }
  return out;
}

std::string FormatPoints3dCsv(const std::vector<Eigen::Vector3d>& p) {
  std::string out = "x,y,z\n";
  for (const auto& q : p) {
    out += FormatDouble(q.x()) + "," + FormatDouble(q.y()) + "," + FormatDouble(q.z()) + "\n";
  }
  return out;
}

std::string FormatImagePointsCsv(const std::vector<Eigen::Vector2d>& uv,
                                 const std::vector<double>* s) {
  if (s && s->size() != uv.size()) {
    throw std::invalid_argument("FormatImagePointsCsv: s.size() != uv.size()");
  }
  std::string out = s ? "s,u,v\n" : "u,v\n";
  for (size_t k = 0; k < uv.size(); ++k) {
    if (s) out += FormatDouble((*s)[k]) + ",";
    out += FormatDouble(uv[k].x()) + "," + FormatDouble(uv[k].y()) + "\n";
  }
  return out;
}

std::string EmitExperimentYaml(const std::string& yaml_text, const Experiment& experiment,
                               const std::function<std::string(const std::string&)>& map_path) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw InputError(experiment.path, e.mark.line >= 0 ? e.mark.line + 1 : 0, "", e.msg);
  }
  YAML::Node cases = root["cases"];
  if (!cases.IsSequence() || cases.size() != experiment.cases.size()) {
    throw InputError(experiment.path, 0, "cases", "changed since it was read");
  }
  for (size_t c = 0; c < experiment.cases.size(); ++c) {
    const StartShape& start = experiment.scene.cases[c].start;
    if (start.kind == StartShape::Kind::kPoints) cases[c]["start"] = map_path(start.file);
    const std::vector<ObservationSpec>& specs = experiment.cases[c].observations;
    if (specs.empty()) continue;
    YAML::Node observations = cases[c]["observations"];
    if (!observations.IsSequence() || observations.size() != specs.size()) {
      throw InputError(experiment.path, experiment.cases[c].line,
                       "cases[" + std::to_string(c) + "].observations", "changed since it was read");
    }
    for (size_t o = 0; o < specs.size(); ++o) {
      YAML::Node entry = observations[o];
      entry["file"] = map_path(specs[o].file);
      if (!specs[o].camera.empty()) entry["camera"] = map_path(specs[o].camera);
      if (!specs[o].mask.empty()) entry["mask"] = map_path(specs[o].mask);
    }
  }
  YAML::Emitter out;
  out << root;
  if (!out.good()) throw InputError(experiment.path, 0, "", "cannot emit YAML: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

std::string FormatTruthJson(const Experiment& experiment, const std::vector<CaseShape>& truth,
                            std::uint32_t seed) {
  // Written by hand for one vertex per line; names escaped by nlohmann::json, numbers at
  // round-trip precision (always finite, so always valid JSON).
  std::string out = "{\n  \"format\": \"rodfit-truth\",\n  \"version\": 1,\n"
                    "  \"rodfit_version\": \"" RODFIT_VERSION "\",\n  \"seed\": " +
                    std::to_string(seed) + ",\n  \"parameters\": {";
  std::map<std::string, double> values;
  for (const auto& [name, spec] : experiment.parameters) values[name] = spec.value;
  // A moving scene's rod density is a parameter its fit may estimate: listed with the rest.
  if (experiment.scene.dynamics)
    for (const MaterialParameterInfo& row : MaterialParameters())
      if (row.rod_field) values[row.name] = experiment.scene.rod.*(row.rod_field);
  bool first = true;
  for (const auto& [name, value] : values) {
    out += std::string(first ? "" : ",") + "\n    " + nlohmann::json(name).dump() + ": " +
           FormatDouble(value);
    first = false;
  }
  out += "\n  },\n  \"cases\": [";
  for (size_t c = 0; c < truth.size(); ++c) {
    out += std::string(c ? "," : "") + "\n    {\n      \"name\": " +
           nlohmann::json(truth[c].name).dump() + ",\n      \"vertices\": [";
    for (int i = 0; i < truth[c].x.cols(); ++i) {
      out += std::string(i ? "," : "") + "\n        [" + FormatDouble(truth[c].x(0, i)) + ", " +
             FormatDouble(truth[c].x(1, i)) + ", " + FormatDouble(truth[c].x(2, i)) + "]";
    }
    out += "\n      ]\n    }";
  }
  out += "\n  ]\n}\n";
  return out;
}

void WriteSynthBundle(const SynthBundle& bundle, const std::string& output_dir,
                      const std::string& experiment_path, const std::vector<InputFile>& inputs) {
  const fs::path dir(output_dir);
  std::error_code ec;
  if (!experiment_path.empty() && fs::exists(dir / kSynthExperimentFile, ec) &&
      fs::equivalent(dir / kSynthExperimentFile, experiment_path, ec)) {
    throw InputError(output_dir, 0, "",
                     "would overwrite the input experiment; write to another directory");
  }
  // Every file into a staging directory first: a run that cannot write its last file (truth.json)
  // leaves none of the others behind.
  StagedDirectory out(output_dir);
  out.SetInputs(inputs);
  for (const auto& [rel, contents] : bundle.files) out.Write(rel, contents);
  out.Commit();
}

}  // namespace rodfit
