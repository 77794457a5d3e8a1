// A haptic log as the device recorded it (experiment keys `unit`, `force_unit`, `device_frame`,
// `force_on` of a grasp_force entry): the fit reads the same grasp positions and forces from the
// scene-frame log and from that log rewritten in a device's millimetres, millinewtons, rotated and
// shifted frame and opposite sign convention; synth writes what such an entry describes; and
// every bad value is a one-line error naming the key.
#include <cmath>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/synth/synth.h"
#include "temp_dir.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/synthesize.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

const char* const kExperiment = R"(rod: {length: 0.15, segments: 20, radius: 0.012, linear_density: 0.45}
parameters:
  bend_stiffness: {value: 2.0e-4}
  twist_stiffness: {value: 1.5e-4}
  stretch_stiffness: {value: 40}
  spring_stiffness: {value: 150, fit: true}
springs:
  - {from: 0.0, to: 0.15}
cases:
  - name: drag
    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
    grasp: {s: 0.1, position: [0.1, 0.015, 0.02]}
    observations:
      - {type: grasp_force, file: log.csv, sigma: 0.01, s: 0.1ENTRY}
)";

std::string Text(const std::string& extra) {
  std::string text = kExperiment;
  return text.replace(text.find("ENTRY"), 5, extra);
}

// The device: 30 degrees about z then 90 about x, its origin at (0.2, -0.1, 0.05) m in the scene.
Eigen::Matrix3d DeviceRotation() {
  return (Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}
const Eigen::Vector3d kDeviceOrigin(0.2, -0.1, 0.05);

std::string Row(double t, const Eigen::Vector3d& p, const Eigen::Vector3d& f) {
  char line[256];
  std::snprintf(line, sizeof(line), "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", t, p.x(), p.y(),
                p.z(), f.x(), f.y(), f.z());
  return line;
}

// A log in the scene's frame, SI, force on the instrument; and the same motion as the device
// records it.
void WriteLogs(TempDir* dir, std::string* scene_path, std::string* device_path) {
  std::string scene = "t,tool_x,tool_y,tool_z,fx,fy,fz\n", device = scene;
  const Eigen::Matrix3d R = DeviceRotation();
  for (int k = 0; k < 30; ++k) {
    const double t = 0.01 * k;
    // Dwells (still) every ten samples, moving in between.
    const double u = std::min(1.0, std::floor(k / 10.0) / 2.0);
    const Eigen::Vector3d p(0.1, 0.015 + 0.01 * u, 0.02 - 0.005 * u);
    const Eigen::Vector3d f(0.1 + 0.02 * u, -0.3 * u, 0.05);
    scene += Row(t, p, f);
    // Device: millimetres, millinewtons, its own axes, the force it applies to the tissue.
    device += Row(t, 1e3 * R.transpose() * (p - kDeviceOrigin), -1e3 * R.transpose() * f);
  }
  *scene_path = dir->Write("scene_log.csv", scene);
  *device_path = dir->Write("device_log.csv", device);
}

std::vector<ForceMeasurement> Forces(const FitInput& input, std::vector<Vec3>* tools) {
  std::vector<ForceMeasurement> out;
  for (const FitCase& c : input.cases) {
    for (const auto& meas : c.measurements)
      if (const auto* forces = dynamic_cast<const ForceReadings*>(meas.get()))
        for (const ForceMeasurement& f : forces->readings()) {
          out.push_back(f);
          tools->push_back(c.load_case.grasp->position);
        }
  }
  return out;
}

std::string DeviceKeys() {
  const Eigen::Matrix3d R = DeviceRotation();
  char text[512];
  std::snprintf(text, sizeof(text),
                ", unit: mm, force_unit: mN, force_on: tissue, device_frame: {rotation: "
                "[[%.17g, %.17g, %.17g], [%.17g, %.17g, %.17g], [%.17g, %.17g, %.17g]], "
                "translation: [0.2, -0.1, 0.05]}",
                R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2));
  return text;
}

TEST(HapticDevice, DeviceLogReadsAsTheSceneLog) {
  TempDir dir;
  std::string scene_log, device_log;
  WriteLogs(&dir, &scene_log, &device_log);
  std::string a = Text(""), b = Text(DeviceKeys());
  a.replace(a.find("log.csv"), 7, "scene_log.csv");
  b.replace(b.find("log.csv"), 7, "device_log.csv");
  const FitInput in_scene = BuildFitInput(LoadExperiment(dir.Write("a.yaml", a)));
  const FitInput in_device = BuildFitInput(LoadExperiment(dir.Write("b.yaml", b)));
  std::vector<Vec3> tools_a, tools_b;
  const auto fa = Forces(in_scene, &tools_a), fb = Forces(in_device, &tools_b);
  // The dwells of both logs pass the quasi-static filter alike (speed in m/s after the unit).
  ASSERT_EQ(fa.size(), fb.size());
  ASSERT_GE(fa.size(), 3u);
  for (size_t k = 0; k < fa.size(); ++k) {
    EXPECT_LT((fa[k].force - fb[k].force).norm(), 1e-12) << k;
    EXPECT_LT((tools_a[k] - tools_b[k]).norm(), 1e-12) << k;
  }
}

TEST(HapticDevice, SynthWritesTheLogTheEntryDescribes) {
  TempDir dir;
  const Experiment plain = LoadExperiment(dir.Write("a.yaml", Text("")));
  const Experiment device = LoadExperiment(dir.Write("b.yaml", Text(DeviceKeys())));
  SynthOptions options;
  options.add_noise = false;
  auto log_of = [](const SynthBundle& bundle) {
    for (const auto& [file, contents] : bundle.files)
      if (file == "log.csv") return CsvTable::Parse(contents, "log.csv");
    ADD_FAILURE() << "no log.csv";
    return CsvTable::Parse("t\n", "log.csv");
  };
  const CsvTable a = log_of(MakeSynthBundle(plain, options));
  const CsvTable b = log_of(MakeSynthBundle(device, options));
  ASSERT_EQ(a.num_rows(), b.num_rows());
  const Eigen::Matrix3d R = DeviceRotation();
  for (int r = 0; r < a.num_rows(); ++r) {
    const Vec3 pa(a.Column("tool_x")[r], a.Column("tool_y")[r], a.Column("tool_z")[r]);
    const Vec3 fa(a.Column("fx")[r], a.Column("fy")[r], a.Column("fz")[r]);
    const Vec3 pb(b.Column("tool_x")[r], b.Column("tool_y")[r], b.Column("tool_z")[r]);
    const Vec3 fb(b.Column("fx")[r], b.Column("fy")[r], b.Column("fz")[r]);
    EXPECT_LT((R * (1e-3 * pb) + kDeviceOrigin - pa).norm(), 1e-12) << r;
    EXPECT_LT((-R * (1e-3 * fb) - fa).norm(), 1e-12 * (1 + fa.norm())) << r;
  }
}

TEST(HapticDevice, BadConventionsAreOneLineErrorsNamingTheKey) {
  TempDir dir;
  std::string scene_log, device_log;
  WriteLogs(&dir, &scene_log, &device_log);
  struct Bad {
    std::string entry, key, message;
  };
  const std::vector<Bad> bad = {
      {", unit: cm", "unit", "must be m or mm"},
      {", force_unit: kgf", "force_unit", "must be N or mN"},
      {", force_on: hand", "force_on", "must be instrument"},
      {", device_frame: {rotation: [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}", "rotation",
       "is not a rotation"},
      {", device_frame: {rotation: [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}", "rotation", "det R = -1"},
      {", device_frame: {rotation: [[1, 0, 0], [0, 1, 0]]}", "rotation", "expected 3 rows"},
      {", device_frame: {scale: 2}", "scale", "rotation, translation"},
  };
  for (const Bad& b : bad) {
    std::string text = Text(b.entry);
    text.replace(text.find("log.csv"), 7, "scene_log.csv");
    const std::string path = dir.Write("bad.yaml", text);
    try {
      LoadExperiment(path);
      ADD_FAILURE() << b.entry << " was accepted";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_THAT(what, HasSubstr("bad.yaml:")) << b.entry;
      EXPECT_THAT(what, HasSubstr(b.key)) << b.entry;
      EXPECT_THAT(what, HasSubstr(b.message)) << b.entry;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
  // Only a haptic log has a device.
  std::string markers = Text("");
  markers.replace(markers.find("{type: grasp_force, file: log.csv, sigma: 0.01, s: 0.1}"),
                  std::string("{type: grasp_force, file: log.csv, sigma: 0.01, s: 0.1}").size(),
                  "{type: markers3d, file: m.csv, sigma: 0.001, unit: mm}");
  EXPECT_THROW(LoadExperiment(dir.Write("m.yaml", markers)), InputError);
}

}  // namespace
}  // namespace rodfit
