// The experiment / scene YAML's blocks and the keys each takes (docs/formats.md, "Scene /
// experiment YAML"), declared once: the reader (io/experiment.cc) checks a block's mapping
// against its table (an unknown key is an error at file:line:key naming the allowed ones) and
// reads only keys the table declares (asking for another is a programming error), and
// tests/io/experiment_blocks_docs_test.cc holds every key to its row of docs/formats.md, and
// every row to a declared key. A new key of a block is one entry here, its reading in the
// reader and its row in the docs.
//
// Not here: the settings blocks (`solver:`, `fit:`, `dynamics:`), which their configurations'
// Serialize declare (rodfit/io/settings.h); the observation entries, whose kinds declare their
// keys (EntryKeys, rodfit/io/experiment.h); and `parameters:`, whose keys are the rows of the
// parameter table (rodfit/model/material_parameters.h) and the spring zones' own parameters.
#pragma once

#include <string>
#include <vector>

namespace rodfit::experiment_blocks {

/// A block of the YAML: where the docs name it (dotted, `[i]` and `[k]` for list items; a block
/// of two places, such as a clamp's frame, names both) and its keys in the order the docs list
/// them, which is also the order an error lists them in.
struct Block {
  std::vector<std::string> paths;
  std::vector<std::string> keys;
};

/// The document itself.
inline const Block kDocument{{""},
                             {"rod", "parameters", "gravity", "gravity_prior_deg", "springs",
                              "section", "cases", "fit", "solver", "dynamics"}};
inline const Block kRod{{"rod"},
                        {"length", "segments", "radius", "linear_density", "rest_curvature",
                         "vertex_s", "rest_shape"}};
/// One entry of `parameters:` (any parameter's).
inline const Block kParameterEntry{{"parameters.NAME"}, {"value", "fit", "min", "max"}};
inline const Block kSection{{"section"}, {"radius", "nodes", "h_factor", "stop_factor"}};
/// One zone of `springs:`.
inline const Block kSpringZone{{"springs"}, {"from", "to", "parameter"}};
/// One case of `cases:`.
inline const Block kCase{{"cases[i]"},
                         {"name", "clamp", "tip_force", "tip_moment", "tip_moment_follower",
                          "point_forces", "point_moments", "cut", "grasp", "poke", "end_clamp",
                          "end_pin", "pins", "start", "symmetry", "observations", "drive",
                          "driven", "tip_load", "initial"}};
/// A held frame: the clamp and the end clamp take the same keys.
inline const Block kHeldFrame{{"cases[i].clamp", "cases[i].end_clamp"},
                              {"position", "tangent", "normal", "rotation_prior_deg",
                               "position_prior"}};
inline const Block kEndPin{{"cases[i].end_pin"}, {"position", "position_prior"}};
/// One entry of each list of a case.
inline const Block kPointForce{{"cases[i].point_forces"}, {"s", "force"}};
inline const Block kPointMoment{{"cases[i].point_moments"}, {"s", "moment"}};
inline const Block kCut{{"cases[i].cut"}, {"from", "to"}};
inline const Block kPin{{"cases[i].pins"}, {"s", "position", "position_prior"}};
inline const Block kGrasp{{"cases[i].grasp"}, {"s", "position", "position_prior"}};
inline const Block kPoke{{"cases[i].poke"}, {"s", "force"}};
inline const Block kSymmetry{{"cases[i].symmetry"}, {"point", "normal"}};
inline const Block kDrive{{"cases[i].drive"}, {"point", "file"}};
inline const Block kDriven{{"cases[i].driven"}, {"s", "file"}};
inline const Block kTipLoad{{"cases[i].tip_load"}, {"file"}};
inline const Block kInitial{{"cases[i].initial"}, {"shape", "velocity", "frames", "frame_interval"}};
/// An observation entry's `device_frame:` (a grasp_force log's device in the scene).
inline const Block kDeviceFrame{{"device_frame"}, {"rotation", "translation"}};

/// Every block above, for the documentation's test.
inline const std::vector<const Block*>& AllBlocks() {
  static const std::vector<const Block*> all = {
      &kDocument, &kRod,        &kParameterEntry, &kSection,  &kSpringZone, &kCase,
      &kHeldFrame, &kEndPin,    &kPointForce,     &kPointMoment, &kCut,     &kPin,
      &kGrasp,    &kPoke,       &kSymmetry,       &kDrive,    &kDriven,     &kTipLoad,
      &kInitial,  &kDeviceFrame};
  return all;
}

}  // namespace rodfit::experiment_blocks
