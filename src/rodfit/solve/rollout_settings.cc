// The rollout's settings (RolloutOptions, rodfit/solve/rollout.h): their one declaration.
#include <string>
#include <vector>

#include "rodfit/solve/rollout.h"

namespace rodfit {

void Serialize(SettingsArchive* a, RolloutOptions* o) {
  std::string held;
  for (int m : o->held_markers) held += (held.empty() ? "" : ",") + std::to_string(m);
  a->Describe("held_markers", "--held",
              "driven markers, comma separated; negative from the last (default " + held + ")");
  a->IntegerList("held_markers", &o->held_markers);

  a->Describe("smooth_frames", "--smooth",
              "held markers' paths smoothed by a centred quadratic over +-N frames (0: as "
              "recorded)");
  a->Integer("smooth_frames", &o->smooth_frames, 0, 1000);

  // The words in the order the help lists them; the default's description says so.
  using Ends = RolloutOptions::HeldEnds;
  const std::vector<Ends> ends = {Ends::kGrippers, Ends::kGrippersPerFrame, Ends::kFreeRoll,
                                  Ends::kJaws, Ends::kPinnedPairs};
  const std::vector<std::string> end_words = {"grippers", "grippers-per-frame", "free-roll", "jaws",
                                              "pins"};
  const std::vector<std::string> end_meaning = {
      "clamps at markers 0 and n-1, their tangents from the first frames, roll by the "
      "minimal-twist frame",
      "as grippers, their tangents from every frame's three end markers (hold 0,1,2,-3,-2,-1)",
      "as grippers, the end free to turn about its tangent",
      "the jaws hold markers 0..1 and n-2..n-1 straight: clamps at markers 1 and n-2 along the "
      "chords",
      "a clamp at marker 0 towards marker 1, markers 1 and n-2 pinned"};
  int end = 0;
  for (size_t k = 0; k < ends.size(); ++k)
    if (ends[k] == o->held_ends) end = static_cast<int>(k);
  auto end_help = [&](int k) {
    return end_words[k] + " (" + (k == end ? "default: " : "") + end_meaning[k] + ")";
  };
  // The default first, then the others in the help's order.
  std::string ends_help = "how the held end markers hold the rod: " + end_help(end);
  std::vector<int> others;
  for (int k = 0; k < static_cast<int>(ends.size()); ++k)
    if (k != end) others.push_back(k);
  for (size_t j = 0; j < others.size(); ++j)
    ends_help += (j + 1 == others.size() ? " or " : ", ") + end_help(others[j]);
  a->Describe("held_ends", "--held-ends", ends_help);
  a->Choice("held_ends", &end, end_words, "must be grippers, grippers-per-frame, free-roll, jaws or pins");
  o->held_ends = ends[end];

  const std::vector<std::string> starts = {"equilibrium", "markers"};
  int start = o->initial_equilibrium ? 0 : 1;
  a->Describe("initial", "--initial",
              starts[0] + (start == 0 ? " (default)" : "") + " or " + starts[1] +
                  (start == 1 ? " (default)" : "") + ": the start shape");
  a->Choice("initial", &start, starts, "must be equilibrium or markers");
  o->initial_equilibrium = start == 0;

  // [m] the scene's dynamics.error_tolerance where it sets none (no command-line option).
  a->Number("error_tolerance", &o->error_tolerance, 0.0, 1.0);
}

}  // namespace rodfit
