// The motion fit's settings (MotionFitOptions, rodfit/fit/motion_fit.h): their one declaration.
#include <cstdio>
#include <string>
#include <vector>

#include "rodfit/fit/motion_fit.h"

namespace rodfit {
namespace {

// A default as the help states it: the shortest text that reads back as the number.
std::string Shortest(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", v);
  return text;
}

}  // namespace

void Serialize(SettingsArchive* a, MotionFitOptions* o) {
  const std::vector<MotionFitMethod> methods = {MotionFitMethod::kLevenbergMarquardt,
                                                MotionFitMethod::kBobyqa};
  const std::vector<std::string> words = {"lm", "bobyqa"};
  const std::vector<std::string> meaning = {
      "least squares with the rollout's exact sensitivities, with covariance",
      "derivative-free on the mean absolute error"};
  int method = 0;
  for (size_t k = 0; k < methods.size(); ++k)
    if (methods[k] == o->method) method = static_cast<int>(k);
  std::string help;
  for (size_t k = 0; k < words.size(); ++k)
    help += (k == 0 ? "" : "; ") + words[k] + (static_cast<int>(k) == method ? " (default)" : "") +
            ": " + meaning[k];
  a->Describe("method", "--method", help);
  a->Choice("method", &method, words, "must be lm or bobyqa");
  o->method = methods[method];

  a->Describe("max_evaluations", "--max-evaluations",
              "rollouts of every recording the fit may take (default " +
                  std::to_string(o->max_evaluations) + ")");
  a->Integer("max_evaluations", &o->max_evaluations, 1, 100000);

  // Each parameter within [start / range, start * range].
  a->Number("range", &o->range, 1.0, 1e12);
  a->Check(o->range > 1.0, "range", "must be > 1");

  a->Describe("marker_sigma", "--marker-sigma",
              "[m] the markers' noise, weighting the fit's residuals");
  a->Number("marker_sigma", &o->marker_sigma, 0.0, 1e9);

  a->Positive("max_log_std", &o->max_log_std);
  a->Bool("trusted_sigmas", &o->trusted_sigmas);

  a->Describe("rest_curvature_knots", "--rest-knots",
              "with --fit rest_curvature: knots evenly along the rod (default " +
                  std::to_string(o->rest_curvature_knots) + ")");
  a->Integer("rest_curvature_knots", &o->rest_curvature_knots, 3, 200);

  a->Describe("rest_curvature_smoothness", "--rest-smoothness",
              "[1/m] with --fit rest_curvature: the std of the curvature's second difference "
              "over neighbouring knots (default " +
                  Shortest(o->rest_curvature_smoothness) + ")");
  a->Number("rest_curvature_smoothness", &o->rest_curvature_smoothness, 1e-9, 1e9);

  a->Positive("max_rest_curvature", &o->max_rest_curvature);  // [1/m]

  a->Describe("gripper_prior_deg", "--gripper-prior-deg",
              "[deg] with --fit and held ends other than pins: each recording's grippers "
              "carry a fitted tilt (about d1 and d2) with a Gaussian prior of this std, reported "
              "per recording, never a parameter of the rod (default " +
                  Shortest(o->gripper_prior_deg) + ": none)");
  a->Number("gripper_prior_deg", &o->gripper_prior_deg, 0.0, 90.0);

  // The rest knots started from the recordings' first frames (MotionFitOptions).
  a->Bool("rest_start_from_first_frames", &o->rest_start_from_first_frames);
}

// The options within their declared ranges (Serialize above: the command line's and the
// library's one range per setting).
bool MotionFitOptions::Check(std::string* why) const {
  MotionFitOptions values = *this;
  SettingsCheck check;
  Serialize(&check, &values);
  if (check.ok()) return true;
  *why = check.why();
  return false;
}

}  // namespace rodfit
