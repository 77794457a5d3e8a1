// Fit report (fit_report.h): tables and plots drawn with OpenCV.
#include "rodfit/io/fit_report.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "rodfit/io/csv.h"
#include "rodfit/io/image_observations.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/vision/camera_file.h"
#include "rodfit/vision/centreline.h"

namespace rodfit {
namespace {

std::string Safe(std::string s) {
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  return s;
}

}  // namespace

void WriteFitReport(const std::string& dir, const Experiment& e, const FitInput& input,
                    const FitResult& result) {
  StagedDirectory out(dir);
  WriteFitReport(&out, e, input, result);
  out.Commit();
}

void WriteFitReport(StagedDirectory* out, const Experiment& e, const FitInput& input,
                    const FitResult& result) {
  // Images are encoded in memory and staged like the tables: nothing reaches DIR before Commit.
  auto write_image = [out](const std::string& name, const cv::Mat& image) {
    out->Write(name, EncodeImage(out->FinalPath(name), image), "plot name");
  };
  std::ostringstream summary, residuals;
  summary << "case,observation,type,count,rms,unit,rms_moment\n";
  residuals << "case,observation,unit,measurement,e1,e2,e3,norm,norm_sigma\n";
  std::vector<std::vector<double>> sigma_norms;  // per case
  for (const ObservationFit& o : result.observations) {
    summary << o.case_name << "," << o.label << "," << o.type << "," << o.num_measurements << ","
            << FormatDouble(o.rms) << "," << o.unit << ","
            << (std::isfinite(o.rms_moment) ? FormatDouble(o.rms_moment) : "") << "\n";
  }
  for (size_t c = 0; c < input.cases.size() && c < result.shapes.size(); ++c) {
    const FitCase& fc = input.cases[c];
    sigma_norms.emplace_back();
    for (size_t k = 0; k < fc.observations.size(); ++k) {
      const Observation& obs = *fc.observations[k];
      VecX r;
      if (!obs.Evaluate(result.shapes[c], &r)) continue;
      const int dim = obs.num_residuals() / std::max(1, obs.num_measurements());
      const bool px = dim == 2;
      for (int m = 0; m < obs.num_measurements(); ++m) {
        double err[3] = {0, 0, 0}, n2 = 0;
        for (int i = 0; i < dim; ++i) {
          err[i] = r[m * dim + i] * obs.sigma();
          n2 += err[i] * err[i];
        }
        const double norm = std::sqrt(n2);
        residuals << fc.load_case.name << "," << fc.labels[k] << "," << (px ? "px" : "m") << ","
                  << m << "," << FormatDouble(err[0]) << "," << FormatDouble(err[1]) << ","
                  << FormatDouble(err[2]) << "," << FormatDouble(norm) << ","
                  << FormatDouble(norm / obs.sigma()) << "\n";
        sigma_norms.back().push_back(norm / obs.sigma());
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
    if (mr.case_index >= 0 && mr.case_index < static_cast<int>(sigma_norms.size()))
      sigma_norms[mr.case_index].push_back(norm / mr.sigma);
  }
  out->Write("summary.csv", summary.str());
  out->Write("residuals.csv", residuals.str());

  // One picture per case and camera: the fitted centre-line projected over the image, or over
  // the observed pixels on a blank frame.
  for (size_t c = 0; c < e.cases.size() && c < result.shapes.size(); ++c) {
    for (size_t k = 0; k < e.cases[c].observations.size(); ++k) {
      const ObservationSpec& spec = e.cases[c].observations[k];
      if (spec.camera.empty()) continue;
      const Camera cam = LoadCamera(spec.camera);
      std::vector<Eigen::Vector2d> fitted;
      for (int i = 0; i < result.shapes[c].cols(); ++i) {
        Eigen::Vector2d uv;
        if (Project(cam, Eigen::Vector3d(result.shapes[c].col(i)), &uv)) fitted.push_back(uv);
      }
      cv::Mat canvas;
      std::vector<Eigen::Vector2d> observed;
      if (spec.type == "images") {
        canvas = ReadImageFile(spec.file);
      } else {
        canvas = cv::Mat(cam.K.height, cam.K.width, CV_8UC3, cv::Scalar(255, 255, 255));
        const CsvTable t = CsvTable::Read(spec.file);
        const auto u = t.Column("u"), v = t.Column("v");
        for (int r = 0; r < t.num_rows(); ++r) observed.emplace_back(u[r], v[r]);
      }
      const cv::Mat overlay = DrawOverlay(canvas, observed, fitted);
      const std::string name = Safe(e.scene.cases[c].name) + "_" +
                               Safe(std::filesystem::path(spec.camera).stem().string()) + "_" +
                               std::to_string(k) + ".png";
      // Safe() leaves no separator; Write holds every name-built output to DIR regardless.
      write_image(name, overlay);
    }
  }

  // Residual plot: |r| / sigma per measurement, cases side by side, with the 1 and 3 sigma lines.
  const int W = 900, H = 360, margin = 40;
  cv::Mat plot(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  size_t total = 0;
  double vmax = 3.5;
  for (const auto& v : sigma_norms) {
    total += v.size();
    for (double x : v) vmax = std::max(vmax, x);
  }
  auto Y = [&](double v) { return static_cast<int>(H - margin - (H - 2 * margin) * v / vmax); };
  for (double level : {1.0, 3.0})
    cv::line(plot, {margin, Y(level)}, {W - margin / 2, Y(level)}, cv::Scalar(200, 200, 200), 1);
  cv::line(plot, {margin, Y(0)}, {W - margin / 2, Y(0)}, cv::Scalar(0, 0, 0), 1);
  size_t idx = 0;
  const cv::Scalar colours[] = {{200, 80, 0}, {0, 140, 0}, {0, 0, 200}, {150, 0, 150}};
  for (size_t c = 0; c < sigma_norms.size(); ++c) {
    for (double v : sigma_norms[c]) {
      const int x = margin + static_cast<int>((W - 1.5 * margin) * (idx + 0.5) / std::max<size_t>(1, total));
      cv::line(plot, {x, Y(0)}, {x, Y(v)}, colours[c % 4], 2);
      ++idx;
    }
  }
  cv::putText(plot, "|residual| / sigma per measurement (grey: 1 and 3 sigma)", {margin, 25},
              cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1);
  write_image("residuals.png", plot);
}

}  // namespace rodfit
