// Fit report (fit_report.h): the CSV tables here, the page in fit_report_page.cc.
#include "rodfit/report/fit_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "rodfit/io/csv.h"
#include "rodfit/report/fit_report_page.h"
#include "rodfit/io/output_dir.h"

namespace rodfit {

std::vector<std::string> WriteFitReport(const std::string& dir, const Experiment& e,
                                        const FitInput& input, const FitResult& result,
                                        const std::vector<std::string>& warnings) {
  StagedDirectory out(dir);
  std::vector<std::string> own = WriteFitReport(&out, e, input, result, warnings);
  out.Commit();
  return own;
}

std::vector<std::string> WriteFitReport(StagedDirectory* out, const Experiment& e,
                                        const FitInput& input, const FitResult& result,
                                        const std::vector<std::string>& warnings) {
  std::ostringstream summary, residuals;
  summary << "case,observation,type,count,rms,unit,rms_moment\n";
  residuals << "case,observation,unit,measurement,e1,e2,e3,norm,norm_sigma\n";
  for (const ObservationFit& o : result.observations) {
    summary << o.case_name << "," << o.label << "," << o.type << "," << o.num_measurements << ","
            << FormatDouble(o.rms) << "," << o.unit << ","
            << (std::isfinite(o.rms_moment) ? FormatDouble(o.rms_moment) : "") << "\n";
  }
  for (size_t c = 0; c < input.cases.size() && c < result.shapes.size(); ++c) {
    const FitCase& fc = input.cases[c];
    // The centre-line observations from the fitted shape; the others' below, from the fit.
    SolvedCase at;
    at.x = &result.shapes[c];
    for (const auto& meas : fc.measurements) {
      if (!meas->reads_vertices_only()) continue;
      std::vector<double> r(meas->num_residuals());
      std::string why;
      if (!meas->Evaluate(at, r.data(), nullptr, &why)) continue;
      for (int m = 0, row = 0; m < meas->num_samples(); ++m) {
        const int dim = meas->sample_rows(m);
        const double sigma = meas->sample_sigma(m);
        double err[3] = {0, 0, 0}, n2 = 0;
        for (int i = 0; i < dim; ++i) {
          err[i] = r[row + i] * sigma;
          n2 += err[i] * err[i];
        }
        row += dim;
        const double norm = std::sqrt(n2);
        residuals << fc.load_case.name << "," << meas->label() << "," << meas->sample_unit(m)
                  << "," << m << "," << FormatDouble(err[0]) << "," << FormatDouble(err[1]) << ","
                  << FormatDouble(err[2]) << "," << FormatDouble(norm) << ","
                  << FormatDouble(norm / sigma) << "\n";
      }
    }
  }
  // Force and moment readings and surface points, after the centre-line observations.
  for (const MeasurementResidual& mr : result.measurement_residuals) {
    const double norm = mr.error.norm();
    residuals << mr.case_name << "," << mr.observation << "," << mr.unit << "," << mr.measurement
              << "," << FormatDouble(mr.error.x()) << "," << FormatDouble(mr.error.y()) << ","
              << FormatDouble(mr.error.z()) << "," << FormatDouble(norm) << ","
              << FormatDouble(norm / mr.sigma) << "\n";
  }
  out->Write("summary.csv", summary.str());
  out->Write("residuals.csv", residuals.str());

  // The page and its figures (fit_report_page.h); index.html last, so that a page never
  // names a figure that was not staged.
  const FitReportPage page = BuildFitReportPage(e, input, result, warnings);
  for (const auto& [name, svg] : page.figures) out->Write("figures/" + name, svg, "figure name");
  out->Write("index.html", page.html);
  return page.warnings;
}

}  // namespace rodfit
