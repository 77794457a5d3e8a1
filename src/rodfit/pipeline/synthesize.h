// `rodfit synth` as a library call (docs/cli.md, "synth"): every case of an experiment solved with
// its parameter values as the truth, and every observation entry's file made by its kind's
// generator (rodfit/pipeline/observation_kind.h; the generators and their measurement model are
// synth's, rodfit/synth/synth.h), gathered in memory before anything is written.
#pragma once

#include <string>

#include "rodfit/io/experiment.h"
#include "rodfit/synth/synth.h"

namespace rodfit {

/// Solves every case of `experiment` and synthesizes all its observation files in memory
/// (experiment.path is read again for DIR/experiment.yaml). Sample positions: markers3d at `s`,
/// else `count` (default: rod segments) evenly spaced with the last at the tip; points3d at
/// `count` (default: segments + 1) arc lengths evenly spaced over [0, L]; image_points with `s`
/// at those markers (s,u,v), else `count` (default: segments + 1) points evenly spaced along the
/// projected centre-line, both ends included (u,v). Image samples whose true or noisy pixel is
/// off the sensor are dropped. grasp_force: `t,tool_x,tool_y,tool_z,fx,fy,fz` as SynthOptions
/// describes (fx.. the force the tissue exerts on the instrument [N]).
/// surface_points: x,y,z of `count` (default: section nodes) points on the case's deformed poke
/// ring, evenly spaced in angle about the section's centre, in the world (noise on x, y, z).
/// In a moving scene (a dynamics: block) the truth is each case's initial equilibrium, and
/// markers3d, points3d and image_points entries are sequences (docs/formats.md, "Observation
/// sequences"): the case run from its initial state and, at every 1 / frame_rate (a `frame`
/// column) or every written frame (a `t` column), the samples above of the shape at that time
/// (closest-point samples, points3d and image_points without s, at the middles of `count`,
/// default segments, equal parts of the rod or its image instead: away from vertices and ends),
/// with a fraction `drop` of them written empty (not seen); pixels off the sensor are left out
/// (a camera that sees nothing at any time is an error).
/// grasp_force also throws InputError for a case without a grasp, an entry whose s grasps
/// another vertex than the case's grasp.s, and a step whose grasp does not converge.
/// Throws InputError (naming the experiment file, the entry's line and key) for a case that does
/// not converge, an unreadable camera file, a camera that sees nothing of the rod, two entries
/// writing the same file, or an `images` file not ending in .png. Nothing is written.
SynthBundle MakeSynthBundle(const Experiment& experiment, const SynthOptions& options = {});

/// MakeSynthBundle then WriteSynthBundle; on an error nothing is written.
SynthBundle Synthesize(const Experiment& experiment, const std::string& output_dir,
                       const SynthOptions& options = {});

}  // namespace rodfit
