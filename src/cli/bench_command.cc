// `rodfit bench [--quick] [--stress] [--skips] -o DIR` (docs/cli.md, "bench"): parses its options,
// runs the scenarios of the bench library (src/rodfit/bench/bench.h) and writes their rows.
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "rodfit/bench/bench.h"
#include "rodfit/io/output_dir.h"

int RunBench(int argc, char** argv) {
  CLI::App app(
      "Solve reference problems with exact answers over a ladder of settings (statics: end "
      "moments, circle and helix, segments 10 to 10,000 and tolerances; a heavy rod clamped at "
      "both ends, a rest-curved 3-D rod, a rod on a Winkler foundation and the cross-section "
      "ring against independent references; dynamics: a "
      "cantilever's first frequency and a damped decay, per integrator and time step; the fit's "
      "recovery of the bundled recipes at noise 0, 1x and 3x); write DIR/bench.csv and "
      "DIR/index.html (error against time) and print a summary. --stress runs the stress suite "
      "instead: every row right or failed with a message, else exit 1. --skips times each skip "
      "of work a scene does not need with and without it instead: the same answer to 1e-10, "
      "else exit 1.",
      "rodfit bench");
  std::string output_dir, calibration_dir = "calibration";
  bool quick = false, stress = false, skips = false;
  app.add_option("-o,--output", output_dir, "output directory, created if missing")->required();
  app.add_flag("--quick", quick, "a shorter ladder (up to 1000 segments, one repeat, no explicit run)");
  app.add_flag("--stress", stress, "the stress suite");
  app.add_flag("--skips", skips, "what each skip saves, timed with and without it");
  app.add_option("--calibration", calibration_dir,
                 "the bundled recipes' folder, for the fit rows (default: ./calibration)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (stress && skips) {
    std::cerr << "rodfit bench: --stress and --skips are separate runs; give one\n";
    return EXIT_FAILURE;
  }
  std::vector<bench::Row> rows;
  if (stress) {
    rows = bench::Stress();
  } else if (skips) {
    rows = bench::Skips(quick, calibration_dir);
  } else {
    rows = bench::Ladder(quick);
    const std::vector<bench::Row> fits = bench::FitRecovery(quick, calibration_dir);
    rows.insert(rows.end(), fits.begin(), fits.end());
  }
  int wrong = 0, different = 0;
  for (const bench::Row& r : rows) {
    wrong += r.verdict == "WRONG";
    different += r.verdict == "DIFFERENT";
  }
  rodfit::StagedDirectory out(output_dir);
  out.Write("bench.csv", bench::Csv(rows), "output file name");
  out.Write("index.html", bench::Html(rows), "output file name");
  const std::string pareto = bench::ParetoSvg(rows);
  if (!pareto.empty()) out.Write("pareto.svg", pareto, "output file name");
  out.Commit();
  if (wrong > 0) {
    std::cerr << "rodfit bench: " << wrong << " stress row(s) returned a wrong answer as success\n";
    return EXIT_FAILURE;
  }
  if (different > 0) {
    std::cerr << "rodfit bench: " << different / 2
              << " skip(s) changed the answer by more than 1e-10\n";
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
