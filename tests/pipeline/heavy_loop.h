// The heavy clamped loop of the critical twist's tests (tests/solve/critical_twist_test.cc) as an
// experiment file, for the pipeline's tests: 1.5 m of wire between coaxial clamps 0.12 m apart,
// both heading +x with d1 = +z, the end clamp at -0.12 x (the tangent turns by -360 degrees),
// gravity -z in the loop's plane, B = 1e-3 N m^2, GJ = B / 1.3, 5 g/m.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "io/temp_dir.h"
#include "rodfit/fit/fit.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/fit_input.h"

namespace rodfit {
namespace test {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kB = 1e-3, kGJ = 1e-3 / 1.3;  // [N m^2] the loop's truth

// The loop; SEGMENTS, END and OBSERVATIONS replaced by each test. EA L^2 / B = 1e8 (a steel
// wire's). It starts from the circle through the clamp going down (loop_start.csv), from which
// the solve moves the end clamp to its place, as the reference's continuation does.
inline const char* const kLoop =
    "rod: {length: 1.5, segments: SEGMENTS, radius: 2.8e-4, linear_density: 5.0e-3}\n"
    "parameters:\n"
    "  bend_stiffness: {value: 1.0e-3, fit: true, min: 1.0e-4, max: 1.0e-2}\n"
    "  twist_stiffness: {value: 7.6923076923076923e-4, fit: true, min: 1.0e-4, max: 1.0e-2}\n"
    "  stretch_stiffness: {value: 44444.444444444444, FIT_EA}\n"
    "gravity: [0, 0, -9.81]\n"
    "cases:\n"
    "  - name: loop\n"
    "    CLAMP\n"
    "    END\n"
    "    start: loop_start.csv\n"
    "    observations:\n"
    "OBSERVATIONS";

inline constexpr char kClamp[] = "clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}";
inline constexpr char kEndClamp[] = "end_clamp: {position: [-0.12, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}";

inline std::string Loop(int segments, const std::string& observations, bool fit_ea = false,
                        const std::string& end = kEndClamp, const std::string& clamp = kClamp) {
  std::string text = kLoop;
  auto put = [&](const std::string& key, const std::string& value) {
    text.replace(text.find(key), key.size(), value);
  };
  put("SEGMENTS", std::to_string(segments));
  put("FIT_EA", fit_ea ? "fit: true" : "fit: false");
  put("CLAMP", clamp);
  put("END", end);
  put("OBSERVATIONS", observations);
  return text;
}

// The circle of the loop's length through the clamp, heading +x and going down first.
inline void WriteStart(const TempDir& dir) {
  const double L = 1.5, R = L / (2 * kPi);
  std::string csv = "s,x,y,z\n";
  for (int k = 0; k <= 400; ++k) {
    const double s = L * k / 400, phi = s / R;
    char row[128];
    std::snprintf(row, sizeof(row), "%.17g,%.17g,0,%.17g\n", s, R * std::sin(phi),
                  -R * (1 - std::cos(phi)));
    csv += row;
  }
  dir.Write("loop_start.csv", csv);
}

inline FitInput LoadLoop(const TempDir& dir, const std::string& text, Experiment* experiment = nullptr) {
  WriteStart(dir);
  const Experiment e = LoadExperiment(dir.Write("loop.yaml", text));
  if (experiment) *experiment = e;
  return BuildFitInput(e);
}

inline std::vector<double> StartLogs(const FitInput& in) {
  std::vector<double> logp;
  for (const Parameter& p : in.parameters)
    if (p.fit) logp.push_back(std::log(p.value));
  return logp;
}

// Markers along the untwisted loop, `s,x,y,z` (their values do not matter for a derivative
// check).
inline std::string LoopMarkers() {
  std::string csv = "s,x,y,z\n";
  const double L = 1.5, R = L / (2 * kPi);
  for (int k = 1; k <= 10; ++k) {
    const double s = L * k / 10.5, phi = s / R;
    char row[128];
    std::snprintf(row, sizeof(row), "%.6f,%.6f,0.01,%.6f\n", s, R * std::sin(phi),
                  -R * (1 - std::cos(phi)));
    csv += row;
  }
  return csv;
}

}  // namespace test
}  // namespace rodfit
