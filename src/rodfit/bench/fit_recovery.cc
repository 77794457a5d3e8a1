// `rodfit bench` fit rows (docs/cli.md, "bench"): how well and how fast the fit recovers the
// parameters of each bundled recipe. The recipe's protocol.yaml holds the truth; `synth` turns it
// into observations with no noise, with the protocol's sigmas (1x) and with three times them
// (3x), the latter two from fixed seeds; the fit starts from the recipe's experiment.yaml
// values. One row per fitted parameter and noise level: error = |fitted / truth - 1|, the fit's
// time (median of repeats, with the spread), its iterations and whether it converged.
#include <stdlib.h>  // mkdtemp

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "rodfit/bench/bench.h"
#include "rodfit/fit/fit.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/synth/synth.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/synthesize.h"

namespace bench {
namespace {

namespace fs = std::filesystem;

constexpr const char* kRecipes[] = {"suture_cantilever", "tissue_drag", "tissue_poke"};

}  // namespace

rodfit::FitInput SynthesizedFitInput(const rodfit::Experiment& protocol,
                                     const rodfit::Experiment& start, double noise,
                                     const std::string& dir) {
  rodfit::Experiment scaled = protocol;
  rodfit::SynthOptions so;
  so.seed = 7;
  so.add_noise = noise > 0.0;
  // The data get `noise` times the sigmas; experiment.yaml keeps the protocol's text, so the fit
  // weighs them with the 1x sigmas. Every sigma is scaled alike, so the relative weights, and
  // with them the estimate, are those of a fit told the scaled sigmas; only the reported
  // residual variance grows.
  for (rodfit::CaseSpec& c : scaled.cases)
    for (rodfit::ObservationSpec& o : c.observations) o.sigma *= std::max(noise, 1.0);
  rodfit::Synthesize(scaled, dir, so);
  rodfit::Experiment e = rodfit::LoadExperiment(dir + "/experiment.yaml");
  e.parameters = start.parameters;
  e.scene.material = start.scene.material;
  return rodfit::BuildFitInput(e);
}

std::vector<Row> FitRecovery(bool quick, const std::string& calibration_dir) {
  std::vector<Row> rows;
  if (!fs::is_directory(calibration_dir)) {
    std::cout << "fit rows: no recipes (" << calibration_dir
              << " is not a folder; run from the repository or pass --calibration DIR)\n";
    return rows;
  }
  const int repeats = quick ? 1 : 3;
  std::string tmp = (fs::temp_directory_path() / "rodfit-bench-fit-XXXXXX").string();
  if (!::mkdtemp(tmp.data())) {
    std::cout << "fit rows: cannot create a temporary folder\n";
    return rows;
  }
  for (const char* recipe : kRecipes) {
    const std::string folder = calibration_dir + "/" + recipe;
    if (!fs::exists(folder + "/protocol.yaml") || !fs::exists(folder + "/experiment.yaml")) {
      std::cout << "fit/" << recipe << ": not in " << calibration_dir << "\n";
      continue;
    }
    const rodfit::Experiment protocol = rodfit::LoadExperiment(folder + "/protocol.yaml");
    const rodfit::Experiment start = rodfit::LoadExperiment(folder + "/experiment.yaml");
    for (double noise : {0.0, 1.0, 3.0}) {
      char setting[32];
      std::snprintf(setting, sizeof(setting), noise == 0.0 ? "noise=0" : "noise=%gx", noise);
      Row base;
      base.problem = std::string("fit/") + recipe;
      base.setting = setting;
      base.error_unit = "relative";
      rodfit::FitResult result;
      try {
        const std::string dir = tmp + "/" + recipe + "_" + std::to_string(static_cast<int>(noise));
        const rodfit::FitInput input = SynthesizedFitInput(protocol, start, noise, dir);
        // The recipe's `fit:` settings, as `rodfit fit` reads them.
        rodfit::FitOptions options = rodfit::FitOptionsOf(start);
        options.num_threads = 1;  // timings without the threads' scheduling noise
        Time(repeats, [&] { result = rodfit::Fit(input, options); }, &base);
      } catch (const std::exception& e) {
        base.family = "-";
        base.error = NAN;
        base.note = e.what();
        Print(base);
        rows.push_back(base);
        continue;
      }
      base.iterations = result.iterations;
      base.converged = result.success;
      base.stable = result.success;
      for (const rodfit::Parameter& p : result.parameters) {
        if (!p.fit) continue;
        const auto truth = protocol.parameters.find(p.name);
        if (truth == protocol.parameters.end()) continue;
        Row row = base;
        row.family = p.name;
        row.error = std::abs(p.value / truth->second.value - 1.0);
        char note[160];
        std::snprintf(note, sizeof(note), "truth %.6g, fitted %.6g%s", truth->second.value,
                      p.value, p.identifiable ? "" : " (not identifiable)");
        row.note = result.success ? note : result.message;
        Print(row);
        rows.push_back(row);
      }
    }
  }
  std::error_code ec;
  fs::remove_all(tmp, ec);
  return rows;
}

}  // namespace bench
