// Tests of `rodfit synth` as a library (synth/synth.h): reproducible bytes for a seed and only for
// that seed, independence of entry order, exact samples on the solved shape without noise, the
// noise and outlier statistics asked for, a self-contained output directory that loads again,
// one-line errors that leave nothing written, and a moving scene's sequences.
#include "rodfit/synth/synth.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/model/rod.h"
#include "rodfit/observe/camera.h"
#include "rodfit/observe/observations.h"
#include "rodfit/solve/case_dynamics.h"
#include "rodfit/solve/statics.h"
#include "rodfit/vision/camera_file.h"
#include "io/temp_dir.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/synthesize.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using test::ReadText;
using test::TempDir;
using ::testing::HasSubstr;

const std::string kCameraFront = RODFIT_SOURCE_DIR "/tests/data/synth/cam_front.yaml";
const std::string kCameraAway = RODFIT_SOURCE_DIR "/tests/data/synth/cam_away.yaml";

// A thread hanging from a horizontal clamp (w L^3 / B = 0.44: a visible sag of about 1 cm) in
// front of cam_front; OBSERVATIONS is replaced by each test's entries.
const char* const kExperiment =
    "rod: {length: 0.2, segments: 40, radius: 2.5e-4, linear_density: 5.6e-5}\n"
    "parameters:\n"
    "  bend_stiffness: {value: 1.0e-5, fit: true, min: 1.0e-8, max: 1.0e-3}\n"
    "  twist_stiffness: {value: 8.0e-6}\n"
    "  stretch_stiffness: {value: 245}\n"
    "gravity: [0, 0, -9.81]\n"
    "cases:\n"
    "  - name: sag\n"
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
    "    tip_force: [0, 2.0e-5, 0]\n"
    "    observations:\n"
    "OBSERVATIONS";

// One entry of each kind; the camera path is absolute, so synth copies it in by its file name.
std::string AllKinds() {
  return "      - {type: markers3d, file: sag_markers.csv, sigma: 3.0e-4, count: 12}\n"
         "      - {type: points3d, file: pts/sag_points.csv, sigma: 3.0e-4, count: 30, "
         "outliers: 0.2}\n"
         "      - {type: image_points, file: sag_uv.csv, camera: " +
         kCameraFront +
         ", sigma: 0.5, count: 40, outliers: 0.1}\n"
         "      - {type: image_points, file: sag_suv.csv, camera: " +
         kCameraFront +
         ", sigma: 0.5, s: [0.05, 0.1, 0.2]}\n"
         "      - {type: images, file: img/sag.png, camera: " +
         kCameraFront + ", sigma: 0.5, blur: 0.7, noise: 3}\n";
}

std::string ExperimentText(const std::string& observations) {
  std::string text = kExperiment;
  text.replace(text.find("OBSERVATIONS"), 12, observations);
  return text;
}

std::map<std::string, std::string> ReadDir(const std::string& dir) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (entry.is_regular_file()) {
      files[fs::relative(entry.path(), dir).generic_string()] = ReadText(entry.path().string());
    }
  }
  return files;
}

std::vector<Eigen::Vector3d> Points(const CsvTable& t) {
  const std::vector<double> x = t.Column("x"), y = t.Column("y"), z = t.Column("z");
  std::vector<Eigen::Vector3d> p;
  for (size_t k = 0; k < x.size(); ++k) p.emplace_back(x[k], y[k], z[k]);
  return p;
}

std::vector<Eigen::Vector2d> Pixels(const CsvTable& t) {
  const std::vector<double> u = t.Column("u"), v = t.Column("v");
  std::vector<Eigen::Vector2d> p;
  for (size_t k = 0; k < u.size(); ++k) p.emplace_back(u[k], v[k]);
  return p;
}

class SynthTest : public ::testing::Test {
 protected:
  Experiment Load(const std::string& observations, const std::string& name = "exp/e.yaml") {
    return LoadExperiment(dir_.Write(name, ExperimentText(observations)));
  }
  // Synthesizes into dir_/NAME and returns the bundle.
  SynthBundle Run(const Experiment& ex, const std::string& name, std::uint32_t seed = 1,
                  bool noise = true) {
    SynthOptions options;
    options.seed = seed;
    options.add_noise = noise;
    return Synthesize(ex, dir_.File(name), options);
  }
  std::string SynthError(const Experiment& ex, const SynthOptions& options = SynthOptions()) {
    try {
      Synthesize(ex, dir_.File("fail"), options);
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
      EXPECT_FALSE(fs::exists(dir_.File("fail"))) << "an output was written";
      return e.what();
    }
    ADD_FAILURE() << "no InputError";
    return "";
  }

  TempDir dir_;
};

TEST_F(SynthTest, SameSeedSameBytesOtherSeedOtherBytes) {
  const Experiment ex = Load(AllKinds());
  Run(ex, "a", 7);
  Run(ex, "b", 7);
  Run(ex, "c", 8);
  const auto a = ReadDir(dir_.File("a")), b = ReadDir(dir_.File("b")), c = ReadDir(dir_.File("c"));
  const std::vector<std::string> expected = {
      "cam_front.yaml", "experiment.yaml", "img/sag.png",  "pts/sag_points.csv",
      "sag_markers.csv", "sag_suv.csv",    "sag_uv.csv",  "truth.json"};
  std::vector<std::string> names;
  for (const auto& [name, bytes] : a) names.push_back(name);
  EXPECT_EQ(names, expected);
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [name, bytes] : a) {
    EXPECT_EQ(bytes, b.at(name)) << name << " differs between two runs with seed 7";
  }
  for (const char* noisy : {"img/sag.png", "pts/sag_points.csv", "sag_markers.csv",
                                   "sag_suv.csv", "sag_uv.csv", "truth.json"}) {
    EXPECT_NE(a.at(noisy), c.at(noisy)) << noisy << " is the same for seeds 7 and 8";
  }
  // The noise-free parts do not depend on the seed.
  EXPECT_EQ(a.at("experiment.yaml"), c.at("experiment.yaml"));
  EXPECT_EQ(a.at("cam_front.yaml"), ReadText(kCameraFront));
}

TEST_F(SynthTest, EntryDataDoesNotDependOnEntryOrder) {
  const std::string m = "      - {type: markers3d, file: m.csv, sigma: 3.0e-4, count: 12}\n";
  const std::string p = "      - {type: points3d, file: p.csv, sigma: 3.0e-4, count: 20}\n";
  const SynthBundle one = MakeSynthBundle(Load(m + p, "one/e.yaml"));
  const SynthBundle two = MakeSynthBundle(Load(p + m, "two/e.yaml"));
  std::map<std::string, std::string> a(one.files.begin(), one.files.end());
  std::map<std::string, std::string> b(two.files.begin(), two.files.end());
  EXPECT_EQ(a.at("m.csv"), b.at("m.csv"));
  EXPECT_EQ(a.at("p.csv"), b.at("p.csv"));
}

TEST_F(SynthTest, TruthIsTheSolvedShapeAndNoiseFreeMarkersLieOnIt) {
  // s at vertices (0.005 per edge) and between them.
  const Experiment ex = Load(
      "      - {type: markers3d, file: m.csv, sigma: 1.0e-3, s: [0, 0.005, 0.0625, 0.1, 0.2]}\n"
      "      - {type: markers3d, file: c.csv, sigma: 1.0e-3, count: 8}\n"
      "      - {type: points3d, file: p.csv, sigma: 1.0e-3, count: 41, outliers: 0.5}\n");
  Run(ex, "out", 1, /*noise=*/false);

  // An independent solve of the case.
  RodModel model(ex.scene.rod, ex.scene.material, ex.scene.gravity, ex.scene.cases[0]);
  RodState state = model.StraightState();
  ASSERT_TRUE(SolveStatics(model, StaticsOptions(), &state).converged);
  const auto truth = nlohmann::json::parse(ReadText(dir_.File("out/truth.json")));
  EXPECT_EQ(truth["format"], "rodfit-truth");
  EXPECT_EQ(truth["version"], 1);
  EXPECT_EQ(truth["seed"], 1);
  EXPECT_EQ(truth["parameters"]["bend_stiffness"], 1.0e-5);
  EXPECT_EQ(truth["parameters"]["stretch_stiffness"], 245.0);
  ASSERT_EQ(truth["cases"].size(), 1u);
  EXPECT_EQ(truth["cases"][0]["name"], "sag");
  const auto& vertices = truth["cases"][0]["vertices"];
  ASSERT_EQ(vertices.size(), 41u);
  for (int i = 0; i <= 40; ++i) {
    for (int d = 0; d < 3; ++d) EXPECT_EQ(vertices[i][d].get<double>(), state.x(d, i));
  }

  // At a vertex's arc length a marker is that vertex, bit for bit; between two it lies on the
  // edge at the fraction of its arc length (round-off only).
  const CsvTable markers = CsvTable::Read(dir_.File("out/m.csv"));
  const std::vector<double> s = markers.Column("s");
  const std::vector<Eigen::Vector3d> p = Points(markers);
  ASSERT_EQ(s, std::vector<double>({0, 0.005, 0.0625, 0.1, 0.2}));
  EXPECT_EQ(p[0], Eigen::Vector3d(state.x.col(0)));
  EXPECT_EQ(p[1], Eigen::Vector3d(state.x.col(1)));
  EXPECT_EQ(p[4], Eigen::Vector3d(state.x.col(40)));
  const Eigen::Vector3d between = state.x.col(12) + 0.5 * (state.x.col(13) - state.x.col(12));
  EXPECT_LT((p[2] - between).norm(), 1e-16);
  EXPECT_LT((p[3] - Eigen::Vector3d(state.x.col(20))).norm(), 1e-16);

  // count markers: evenly spaced, the last at the tip.
  const CsvTable counted = CsvTable::Read(dir_.File("out/c.csv"));
  const std::vector<double> cs = counted.Column("s");
  ASSERT_EQ(cs.size(), 8u);
  for (int k = 0; k < 8; ++k) EXPECT_NEAR(cs[k], 0.2 * (k + 1) / 8, 1e-15);
  EXPECT_EQ(Points(counted).back(), Eigen::Vector3d(state.x.col(40)));

  // points3d without noise: every vertex (41 evenly spaced samples), no outliers either.
  const std::vector<Eigen::Vector3d> pts = Points(CsvTable::Read(dir_.File("out/p.csv")));
  ASSERT_EQ(pts.size(), 41u);
  for (int i = 0; i <= 40; ++i) EXPECT_LT((pts[i] - state.x.col(i)).norm(), 1e-15) << i;
}

TEST_F(SynthTest, NoiseHasTheEntrysSigma) {
  // 300 markers: 900 residual coordinates, so the sample std is within ~2.4% (1 sd) of sigma;
  // 15% is over 6 sd.
  const double sigma_m = 1.0e-3, sigma_px = 0.5;
  const std::string entries =
      "      - {type: markers3d, file: m.csv, sigma: 1.0e-3, count: 300}\n"
      "      - {type: image_points, file: uv.csv, camera: " +
      kCameraFront + ", sigma: 0.5, count: 300}\n";
  const Experiment ex = Load(entries);
  Run(ex, "noisy", 3);
  const SynthBundle exact = Run(ex, "exact", 3, false);

  const CsvTable markers = CsvTable::Read(dir_.File("noisy/m.csv"));
  const std::vector<double> s = markers.Column("s");
  const std::vector<Eigen::Vector3d> p = Points(markers);
  ASSERT_EQ(p.size(), 300u);
  double sum = 0.0, sum_sq = 0.0;
  for (size_t k = 0; k < p.size(); ++k) {
    const Eigen::Vector3d r = p[k] - PointAtArcLength(exact.truth[0], s[k]);
    sum += r.sum();
    sum_sq += r.squaredNorm();
  }
  const double n = 3.0 * p.size();
  EXPECT_LT(std::abs(sum / n), 4.0 * sigma_m / std::sqrt(n));  // mean: 4 standard errors
  const double std_m = std::sqrt((sum_sq - sum * sum / n) / (n - 1));
  EXPECT_NEAR(std_m, sigma_m, 0.15 * sigma_m);

  // Pixels: the same samples without noise are the truth (all 300 are on the sensor).
  const std::vector<Eigen::Vector2d> uv = Pixels(CsvTable::Read(dir_.File("noisy/uv.csv")));
  const std::vector<Eigen::Vector2d> uv0 = Pixels(CsvTable::Read(dir_.File("exact/uv.csv")));
  ASSERT_EQ(uv.size(), 300u);
  ASSERT_EQ(uv0.size(), 300u);
  sum = sum_sq = 0.0;
  for (size_t k = 0; k < uv.size(); ++k) {
    const Eigen::Vector2d r = uv[k] - uv0[k];
    sum += r.sum();
    sum_sq += r.squaredNorm();
  }
  const double m = 2.0 * uv.size();
  const double std_px = std::sqrt((sum_sq - sum * sum / m) / (m - 1));
  EXPECT_NEAR(std_px, sigma_px, 0.15 * sigma_px);
}

TEST_F(SynthTest, OutlierFractionIsHonoured) {
  // sigma is tiny against the outlier box (the rod's bounding box grown by 2 cm), so a sample
  // more than 20 sigma from its true position is an outlier; one landing that close to its own
  // true point has a probability of about 1e-9.
  const std::string entries =
      "      - {type: points3d, file: p.csv, sigma: 1.0e-5, count: 400, outliers: 0.25}\n"
      "      - {type: markers3d, file: m.csv, sigma: 1.0e-5, count: 201, outliers: 0.1}\n"
      "      - {type: image_points, file: uv.csv, camera: " +
      kCameraFront + ", sigma: 0.01, count: 250, outliers: 0.3}\n";
  const Experiment ex = Load(entries);
  Run(ex, "noisy", 5);
  const SynthBundle exact = Run(ex, "exact", 5, false);

  const auto count_far3 = [&](const std::string& file, double limit) {
    const auto p = Points(CsvTable::Read(dir_.File("noisy/" + file)));
    const auto q = Points(CsvTable::Read(dir_.File("exact/" + file)));
    EXPECT_EQ(p.size(), q.size());
    int far = 0;
    for (size_t k = 0; k < p.size(); ++k) far += (p[k] - q[k]).norm() > limit;
    return far;
  };
  EXPECT_EQ(count_far3("p.csv", 20 * 1.0e-5), 100);  // 0.25 * 400
  EXPECT_EQ(count_far3("m.csv", 20 * 1.0e-5), 20);   // round(0.1 * 201)

  const auto uv = Pixels(CsvTable::Read(dir_.File("noisy/uv.csv")));
  const auto uv0 = Pixels(CsvTable::Read(dir_.File("exact/uv.csv")));
  ASSERT_EQ(uv.size(), 250u);
  int far = 0;
  Camera camera = LoadCamera(kCameraFront);
  for (size_t k = 0; k < uv.size(); ++k) {
    far += (uv[k] - uv0[k]).norm() > 20 * 0.01;
    EXPECT_TRUE(camera.InImage(uv[k])) << k;  // image outliers are drawn on the sensor
  }
  EXPECT_EQ(far, 75);  // 0.3 * 250
}

TEST_F(SynthTest, OutputDirectoryIsSelfContainedAndLoads) {
  const Experiment ex = Load(AllKinds());
  Run(ex, "out");
  const std::string dir = dir_.File("out");
  const Experiment back = LoadExperiment(dir + "/experiment.yaml");
  EXPECT_EQ(back.scene.rod.segments, 40);
  EXPECT_EQ(back.scene.rod.radius, 2.5e-4);
  EXPECT_EQ(back.parameters.at("bend_stiffness").value, 1.0e-5);
  EXPECT_TRUE(back.parameters.at("bend_stiffness").fit);
  EXPECT_EQ(*back.parameters.at("bend_stiffness").max, 1.0e-3);
  EXPECT_EQ(back.scene.cases[0].tip_force, Vec3(0, 2.0e-5, 0));
  ASSERT_EQ(back.cases[0].observations.size(), 5u);
  for (size_t o = 0; o < 5; ++o) {
    const ObservationSpec& b = back.cases[0].observations[o];
    const ObservationSpec& a = ex.cases[0].observations[o];
    EXPECT_EQ(b.type, a.type);
    EXPECT_EQ(b.sigma, a.sigma);
    EXPECT_EQ(b.count, a.count);
    EXPECT_EQ(b.s, a.s);
    EXPECT_EQ(b.outliers, a.outliers);
    EXPECT_EQ(b.blur, a.blur);
    EXPECT_EQ(b.noise, a.noise);
    EXPECT_EQ(b.file.rfind(dir + "/", 0), 0u) << b.file << " is not in " << dir;
    EXPECT_TRUE(fs::is_regular_file(b.file)) << b.file;
    if (!a.camera.empty()) {
      EXPECT_EQ(b.camera, dir + "/cam_front.yaml");
      EXPECT_TRUE(fs::is_regular_file(b.camera));
    }
  }
  EXPECT_EQ(back.cases[0].observations[1].file, dir + "/pts/sag_points.csv");
  EXPECT_EQ(back.cases[0].observations[4].file, dir + "/img/sag.png");
  // The moved copy still reads: nothing in it points outside the folder.
  fs::rename(dir, dir_.File("moved"));
  EXPECT_NO_THROW(MakeSynthBundle(LoadExperiment(dir_.File("moved/experiment.yaml"))));
}

TEST_F(SynthTest, AnImageEntrysRoiAndMaskAreKeptAndTheMaskCopied) {
  dir_.Write("exp/masks/front.png", "mask bytes, copied as they are");
  const Experiment ex = Load("      - {type: images, file: img/sag.png, camera: " + kCameraFront +
                             ", sigma: 0.5, roi: [100, 50, 1200, 1000], mask: masks/front.png}\n");
  Run(ex, "out");
  const std::string dir = dir_.File("out");
  const Experiment back = LoadExperiment(dir + "/experiment.yaml");
  const ObservationSpec& b = back.cases[0].observations[0];
  ASSERT_TRUE(b.roi.has_value());
  EXPECT_EQ(*b.roi, (std::array<int, 4>{100, 50, 1200, 1000}));
  EXPECT_EQ(b.mask, dir + "/masks/front.png");
  EXPECT_EQ(ReadText(b.mask), "mask bytes, copied as they are");
  // A mask that is not there is named (synth copies it).
  const Experiment missing = Load("      - {type: images, file: img/sag.png, camera: " +
                                  kCameraFront + ", sigma: 0.5, mask: masks/none.png}\n");
  EXPECT_THAT(SynthError(missing), HasSubstr("masks/none.png"));
}

TEST_F(SynthTest, PixelsOffTheSensorAreDropped) {
  // cam_front with its principal point moved 500 px left: the rod's clamp half leaves the image.
  std::string camera = ReadText(kCameraFront);
  camera.replace(camera.find("643.2"), 5, "143.2");
  dir_.Write("exp/half.yaml", camera);
  const Experiment ex = Load(
      "      - {type: image_points, file: uv.csv, camera: half.yaml, sigma: 0.5, count: 101}\n"
      "      - {type: image_points, file: suv.csv, camera: half.yaml, sigma: 0.5, "
      "s: [0.01, 0.19]}\n"
      "      - {type: images, file: half.png, camera: half.yaml, sigma: 0.5}\n");
  const SynthBundle bundle = MakeSynthBundle(ex);
  const Camera half = LoadCamera(dir_.File("exp/half.yaml"));
  const std::vector<Eigen::Vector2d> uv = Pixels(CsvTable::Parse(bundle.files[0].second, "uv"));
  EXPECT_GT(uv.size(), 30u);
  EXPECT_LT(uv.size(), 70u);
  for (const Eigen::Vector2d& p : uv) EXPECT_TRUE(half.InImage(p)) << p.transpose();
  EXPECT_THAT(bundle.report[0], HasSubstr("outside the image dropped"));
  // With s: the marker near the clamp is off the sensor, the one near the tip stays.
  const CsvTable suv = CsvTable::Parse(bundle.files[1].second, "suv");
  EXPECT_EQ(suv.Column("s"), std::vector<double>({0.19}));
}

TEST_F(SynthTest, PathsOutsideTheExperimentFolderAreFlattened) {
  EXPECT_EQ(SynthRelativePath("/a/b/c/m.csv", "/a/b"), "c/m.csv");
  EXPECT_EQ(SynthRelativePath("/a/x/m.csv", "/a/b"), "m.csv");
  EXPECT_EQ(SynthRelativePath("/a/b/../b/m.csv", "/a/b/"), "m.csv");
  const Experiment ex = Load("      - {type: markers3d, file: ../up.csv, sigma: 1.0e-3}\n");
  const SynthBundle bundle = MakeSynthBundle(ex);
  EXPECT_EQ(bundle.files[0].first, "up.csv");
  // Default count: one marker per free vertex.
  EXPECT_EQ(CsvTable::Parse(bundle.files[0].second, "up.csv").num_rows(), 40);
}

TEST_F(SynthTest, ErrorsNameTheEntryAndWriteNothing) {
  // A camera looking away from the rod: the camera file and the case are named.
  const std::string away = SynthError(Load(
      "      - {type: images, file: a.png, camera: " + kCameraAway + ", sigma: 0.5}\n"));
  EXPECT_THAT(away, HasSubstr("e.yaml:12: cases[0].observations[0]: camera " + kCameraAway +
                              " sees nothing of the rod in case 'sag'"));
  EXPECT_THAT(SynthError(Load("      - {type: image_points, file: a.csv, camera: " +
                              kCameraAway + ", sigma: 0.5, count: 5}\n")),
              HasSubstr("sees nothing of the rod in case 'sag'"));

  // Unreadable or malformed camera file.
  EXPECT_THAT(SynthError(Load("      - {type: images, file: a.png, camera: nocam.yaml, "
                              "sigma: 0.5}\n")),
              HasSubstr("cases[0].observations[0].camera: "));
  dir_.Write("exp/bad.yaml", "%YAML:1.0\n---\ncamera_matrix: [1, 2\n");
  EXPECT_THAT(SynthError(Load("      - {type: images, file: a.png, camera: bad.yaml, "
                              "sigma: 0.5}\n")),
              HasSubstr("cases[0].observations[0].camera: " + dir_.File("exp/bad.yaml")));

  // Two entries writing one file; an entry writing over experiment.yaml; not a PNG.
  EXPECT_THAT(SynthError(Load("      - {type: markers3d, file: m.csv, sigma: 1.0e-3}\n"
                              "      - {type: points3d, file: m.csv, sigma: 1.0e-3}\n")),
              HasSubstr("cases[0].observations[1].file: writes m.csv, which "
                        "cases[0].observations[0] writes"));
  EXPECT_THAT(SynthError(Load("      - {type: markers3d, file: experiment.yaml, sigma: 1}\n")),
              HasSubstr("writes experiment.yaml"));
  EXPECT_THAT(SynthError(Load("      - {type: images, file: a.jpg, camera: " + kCameraFront +
                              ", sigma: 0.5}\n")),
              HasSubstr("name the file *.png"));

  // A case that does not converge (one Newton iteration allowed) is named.
  SynthOptions one_step;
  one_step.statics.max_iterations = 1;
  EXPECT_THAT(SynthError(Load("      - {type: markers3d, file: m.csv, sigma: 1.0e-3}\n"),
                         one_step),
              HasSubstr("e.yaml:8: cases[0]: case 'sag' does not converge"));
}

TEST_F(SynthTest, BundledDemoSynthesizes) {
  // data/synth_demo is what the README runs: two cameras, markers, pixels and images.
  const Experiment ex = LoadExperiment(RODFIT_SOURCE_DIR "/data/synth_demo/experiment.yaml");
  const SynthBundle bundle = MakeSynthBundle(ex);
  std::map<std::string, std::string> files(bundle.files.begin(), bundle.files.end());
  EXPECT_EQ(files.size(), 12u);
  for (const char* name : {"sag_markers.csv", "sag_front_uv.csv", "sag_front.png", "sag_top.png",
                           "pulled_markers.csv", "pulled_top_suv.csv", "pulled_front.png",
                           "pulled_top.png", "cam_front.yaml", "cam_top.yaml", "experiment.yaml",
                           "truth.json"}) {
    EXPECT_TRUE(files.count(name)) << name;
  }
  // Every tracked pixel is on the sensor: nothing was dropped.
  EXPECT_EQ(CsvTable::Parse(files.at("sag_front_uv.csv"), "uv").num_rows(), 60);
  EXPECT_EQ(CsvTable::Parse(files.at("pulled_top_suv.csv"), "suv").num_rows(), 4);
}

TEST_F(SynthTest, RefusesToOverwriteTheInputExperiment) {
  const std::string path = dir_.Write("exp/experiment.yaml",
                                      ExperimentText("      - {type: markers3d, file: m.csv, "
                                                     "sigma: 1.0e-3}\n"));
  const Experiment ex = LoadExperiment(path);
  try {
    Synthesize(ex, dir_.File("exp"));
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("would overwrite the input experiment"));
  }
  EXPECT_FALSE(fs::exists(dir_.File("exp/m.csv")));
  EXPECT_EQ(ReadText(path), ExperimentText("      - {type: markers3d, file: m.csv, "
                                           "sigma: 1.0e-3}\n"));
}

// A moving scene's pixel and point sequences (docs/formats.md, "Files `synth` writes"): without
// noise, pixel markers are the camera's projections of the run's markers, centre-line pixels and
// 3-D points lie on the run's shape at their times (between its vertices), one row per sample
// and frame; with noise, the fraction `drop` is written empty.
TEST_F(SynthTest, MovingSceneWritesPixelAndPointSequences) {
  const std::string camera = RODFIT_SOURCE_DIR "/tests/data/synth/cam_swing.yaml";
  const std::string yaml =
      "rod: {length: 0.2, segments: 10, radius: 1.25e-4, linear_density: 5.6e-5}\n"
      "parameters:\n"
      "  bend_stiffness: {value: 9.6e-7}\n"
      "  twist_stiffness: {value: 8.0e-7}\n"
      "  stretch_stiffness: {value: 245}\n"
      "  damping: {value: 2.0e-4}\n"
      "gravity: [0, 0, -9.81]\n"
      "dynamics: {time_step: 2.5e-3, duration: 0.1, integrator: bdf2}\n"
      "cases:\n"
      "  - name: swing\n"
      "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
      "    initial: {shape: start}\n"
      "    observations:\n"
      "      - {type: image_points, file: suv.csv, camera: " + camera +
      ", sigma: 0.5, s: [0.1, 0.2], frame_rate: 50, drop: 0.25}\n"
      "      - {type: image_points, file: uv.csv, camera: " + camera +
      ", sigma: 0.5, count: 4, drop: 0.25}\n"
      "      - {type: points3d, file: p.csv, sigma: 1.0e-3, frame_rate: 100}\n";
  const Experiment ex = LoadExperiment(dir_.Write("exp/swing.yaml", yaml));
  Run(ex, "exact", 1, /*noise=*/false);
  const Camera cam = LoadCamera(camera);
  const std::vector<double> arc = {0,    0.02, 0.04, 0.06, 0.08, 0.1,
                                   0.12, 0.14, 0.16, 0.18, 0.2};

  // Pixel markers at 50 Hz: frames 0..5, two markers each, the projections of the run's points.
  const CsvTable suv = CsvTable::Read(dir_.File("exact/suv.csv"));
  EXPECT_EQ(suv.header(), (std::vector<std::string>{"frame", "s", "u", "v"}));
  ASSERT_EQ(suv.num_rows(), 6 * 2);
  std::vector<double> t;
  for (int k = 0; k <= 5; ++k) t.push_back(0.02 * k);
  const CaseSamples markers =
      SampleCaseDynamics(ex.scene, 0, StaticsOptions(), {0.1, 0.2}, t, {});
  ASSERT_TRUE(markers.ok) << markers.reason;
  const std::vector<double> frame = suv.Column("frame"), s = suv.Column("s");
  const std::vector<Eigen::Vector2d> uv = Pixels(suv);
  for (int r = 0; r < suv.num_rows(); ++r) {
    EXPECT_EQ(frame[r], r / 2);
    EXPECT_EQ(s[r], r % 2 ? 0.2 : 0.1);
    Eigen::Vector2d expected;
    ASSERT_TRUE(Project(cam, Eigen::Vector3d(markers.x[r / 2].col(r % 2)), &expected));
    EXPECT_LT((uv[r] - expected).norm(), 1e-9) << "row " << r;
  }

  // Centre-line pixels at every written step (a t column): 4 per frame, on the projected shape
  // and away from its vertices (the middles of 4 equal parts of its image).
  const CsvTable curve = CsvTable::Read(dir_.File("exact/uv.csv"));
  EXPECT_EQ(curve.header(), (std::vector<std::string>{"t", "u", "v"}));
  ASSERT_EQ(curve.num_rows(), 41 * 4);
  const std::vector<double> curve_t = curve.Column("t");
  std::vector<double> steps;
  for (int k = 0; k <= 40; ++k) steps.push_back(2.5e-3 * k);
  const CaseSamples shapes = SampleCaseDynamics(ex.scene, 0, StaticsOptions(), arc, steps, {});
  ASSERT_TRUE(shapes.ok) << shapes.reason;
  const std::vector<Eigen::Vector2d> curve_uv = Pixels(curve);
  for (int r = 0; r < curve.num_rows(); ++r) {
    const int k = r / 4;
    EXPECT_NEAR(curve_t[r], steps[k], 1e-15);
    Eigen::Matrix2Xd image(2, arc.size());
    for (size_t i = 0; i < arc.size(); ++i) {
      Eigen::Vector2d p;
      ASSERT_TRUE(Project(cam, Eigen::Vector3d(shapes.x[k].col(i)), &p));
      image.col(i) = p;
    }
    const PolylineFoot foot = ClosestPointOnPolyline<2>(image, curve_uv[r]);
    EXPECT_LT(std::sqrt(foot.distance_squared), 1e-9) << "row " << r;
    EXPECT_EQ(foot.vertex, -1) << "row " << r;  // strictly inside an edge
  }

  // 3-D points at 100 Hz: 10 per frame (one per edge), each the middle of its edge.
  const CsvTable points = CsvTable::Read(dir_.File("exact/p.csv"));
  EXPECT_EQ(points.header(), (std::vector<std::string>{"frame", "x", "y", "z"}));
  ASSERT_EQ(points.num_rows(), 11 * 10);
  const std::vector<Eigen::Vector3d> p = Points(points);
  for (int r = 0; r < points.num_rows(); ++r) {
    const int k = r / 10, j = r % 10;  // frame k at 0.01 k s is step 4 k
    const Eigen::Vector3d middle = 0.5 * (shapes.x[4 * k].col(j) + shapes.x[4 * k].col(j + 1));
    EXPECT_LT((p[r] - middle).norm(), 1e-15) << "row " << r;
  }

  // With noise: a quarter of the samples written empty (not seen).
  Run(ex, "noisy", 1, /*noise=*/true);
  const std::string text = ReadText(dir_.File("noisy/uv.csv"));
  size_t empty = 0;
  for (size_t at = text.find(",,\n"); at != std::string::npos; at = text.find(",,\n", at + 1))
    ++empty;
  EXPECT_EQ(empty, 41u);  // round(0.25 * 164)
}

// Found by the fuzz corpus (tests/cli/fuzz_corpus_test.cc): a sequence's sample times were
// listed before their number was checked, so frame_rate: 1e12 allocated until the machine ran out
// and 1e308 overflowed the count (a header-only file, written as a success); an entry's file
// naming a folder failed naming no entry.
TEST_F(SynthTest, AMovingEntrysSampleTimesAreCountedBeforeTheyAreListed) {
  auto moving = [&](const std::string& entry,
                    const std::string& dynamics = "{time_step: 2.5e-3, duration: 0.05}") {
    return LoadExperiment(dir_.Write(
        "exp/swing.yaml",
        "rod: {length: 0.2, segments: 10, radius: 1.25e-4, linear_density: 5.6e-5}\n"
        "parameters:\n"
        "  bend_stiffness: {value: 9.6e-7}\n"
        "  twist_stiffness: {value: 8.0e-7}\n"
        "  stretch_stiffness: {value: 245}\n"
        "dynamics: " + dynamics + "\n"
        "cases:\n"
        "  - name: swing\n"
        "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
        "    initial: {shape: start}\n"
        "    observations:\n"
        "      - " + entry + "\n"));
  };
  for (const char* rate : {"1e12", "1e308", "2.1e7"}) {
    for (const std::string& entry :
         {"{type: markers3d, file: m.csv, sigma: 1.0e-3, s: [0.2], frame_rate: " +
              std::string(rate) + "}",
          "{type: points3d, file: p.csv, sigma: 1.0e-3, count: 1, frame_rate: " +
              std::string(rate) + "}",
          "{type: reaction, file: r.csv, point: clamp, sigma: 1.0e-6, frame_rate: " +
              std::string(rate) + "}"})
      EXPECT_THAT(SynthError(moving(entry)),
                  HasSubstr("swing.yaml:12: cases[0].observations[0]: ")) << entry;
  }
  EXPECT_THAT(SynthError(moving("{type: reaction, file: r.csv, point: clamp, sigma: 1.0e-6, "
                                "frame_rate: 1e12}")),
              HasSubstr("5e+10 sample times (dynamics.duration x frame_rate), above the limit of "
                        "1000000 rows"));
  // Without frame_rate every written step: 1e6 steps of 1e-4 s are 1e6 + 1 times.
  EXPECT_THAT(SynthError(moving("{type: reaction, file: r.csv, point: clamp, sigma: 1.0e-6}",
                                "{time_step: 1.0e-4, duration: 100}")),
              HasSubstr("1000001 sample times (every written step of the dynamics), above the "
                        "limit of 1000000 rows (give frame_rate, or raise dynamics.output_every)"));
  // 2.1e7 Hz above (1.05e6 times over 0.05 s); 1e-308 Hz samples t = 0 alone.
  Run(moving("{type: reaction, file: r.csv, point: clamp, sigma: 1.0e-6, frame_rate: 1e-308}"),
      "one");
  EXPECT_EQ(CsvTable::Read(dir_.File("one/r.csv")).num_rows(), 1);

  for (const char* folder : {".", "..", "sub/"})
    EXPECT_THAT(SynthError(moving("{type: reaction, file: " + std::string(folder) +
                                  ", point: clamp, sigma: 1.0e-6}")),
                HasSubstr("swing.yaml:12: cases[0].observations[0].file: names a folder, not a "
                          "file to write"))
        << folder;
}

}  // namespace
}  // namespace rodfit
