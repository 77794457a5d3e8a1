// Tests of the moving experiment's observations (docs/formats.md, "Observation sequences"): the
// reader's keys (frame_rate, drop, a fitted damping, what a moving scene allows) and the
// sequence files (t or frame column, missing samples; markers3d, points3d and image_points with
// and without s, one static observation per frame); every bad input is a one-line InputError
// naming the file, the 1-based line and the key or column.
#include "rodfit/pipeline/sequence_input.h"

#include <cmath>
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/errors.h"
#include "temp_dir.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

// A valid moving experiment; the tests change one line each, so the line numbers hold.
const char* const kMoving =
    "rod: {length: 0.2, segments: 10, radius: 1.0e-4, linear_density: 5.0e-5}\n"  // 1
    "parameters:\n"                                                                // 2
    "  bend_stiffness: {value: 1.0e-6, fit: true}\n"                               // 3
    "  twist_stiffness: {value: 8.0e-7}\n"                                         // 4
    "  stretch_stiffness: {value: 245}\n"                                          // 5
    "  damping: {value: 1.0e-4, fit: true, min: 1.0e-6, max: 1.0e-2}\n"           // 6
    "dynamics: {time_step: 1.0e-3, duration: 0.1, integrator: bdf2}\n"             // 7
    "cases:\n"                                                                     // 8
    "  - name: swing\n"                                                            // 9
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"    // 10
    "    initial: {shape: start}\n"                                                // 11
    "    observations:\n"                                                          // 12
    "      - {type: markers3d, file: seq.csv, sigma: 5.0e-4, s: [0.1, 0.2], frame_rate: 100, "
    "drop: 0.1}\n";                                                                // 13

class MarkerSequencesTest : public ::testing::Test {
 protected:
  static std::string With(const std::string& from, const std::string& to) {
    std::string text = kMoving;
    const size_t pos = text.find(from);
    EXPECT_NE(pos, std::string::npos) << from;
    if (pos != std::string::npos) text.replace(pos, from.size(), to);
    return text;
  }

  // The InputError's message of loading `yaml` (and, when `csv` is given, reading the sequences
  // with seq.csv holding it); "" and a failure if none.
  std::string Error(const std::string& yaml, const std::string& csv = "") {
    const std::string path = dir_.Write("scene.yaml", yaml);
    if (!csv.empty()) dir_.Write("seq.csv", csv);
    try {
      const Experiment ex = LoadExperiment(path);
      if (!csv.empty()) BuildSequenceInput(ex);
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "not one line";
      return e.what();
    }
    ADD_FAILURE() << "no InputError for:\n" << yaml << "\n" << csv;
    return "";
  }

  void ExpectError(const std::string& yaml, int line, const std::string& key) {
    EXPECT_THAT(Error(yaml),
                HasSubstr(dir_.File("scene.yaml") + ":" + std::to_string(line) + ": " + key + ":"));
  }
  void ExpectCsvError(const std::string& csv, int line, const std::string& column,
                      const std::string& yaml = kMoving) {
    EXPECT_THAT(Error(yaml, csv),
                HasSubstr(dir_.File("seq.csv") + ":" + std::to_string(line) + ": " + column + ":"));
  }

  TempDir dir_;
};

TEST_F(MarkerSequencesTest, MovingExperimentReadsItsKeys) {
  const Experiment ex = LoadExperiment(dir_.Write("scene.yaml", kMoving));
  ASSERT_EQ(ex.cases.size(), 1u);
  const ObservationSpec& o = ex.cases[0].observations.at(0);
  EXPECT_EQ(o.frame_rate, 100.0);
  EXPECT_EQ(o.drop, 0.1);
  EXPECT_TRUE(ex.parameters.at("damping").fit);
  EXPECT_EQ(*ex.parameters.at("damping").min, 1.0e-6);
  EXPECT_EQ(FittedNames(ex), (std::vector<std::string>{"bend_stiffness", "damping"}));
  const MotionFitOptions options = SequenceFitOptionsOf(ex, FittedNames(ex));
  ASSERT_EQ(options.lower.size(), 2u);
  EXPECT_TRUE(std::isnan(options.lower[0]));  // bend_stiffness: no min, the default range
  EXPECT_EQ(options.lower[1], 1.0e-6);
  EXPECT_EQ(options.upper[1], 1.0e-2);
}

TEST_F(MarkerSequencesTest, FittedDampingNeedsMotion) {
  // Without the dynamics: block there is no motion to identify damping from.
  ExpectError(With("dynamics: {time_step: 1.0e-3, duration: 0.1, integrator: bdf2}\n", ""), 6,
              "parameters.damping.fit");
}

TEST_F(MarkerSequencesTest, SequenceKeysOnlyInAMovingScene) {
  // A static scene (no dynamics:, no initial:) with frame_rate on its markers3d.
  std::string text = With("dynamics: {time_step: 1.0e-3, duration: 0.1, integrator: bdf2}\n",
                          "gravity: [0, 0, -9.81]\n");
  text = text.replace(text.find("    initial: {shape: start}\n"), 28, "    tip_force: [0, 0, 0]\n");
  text = text.replace(text.find("fit: true, min"), 9, "fit: false");
  EXPECT_THAT(Error(text), HasSubstr(":13: cases[0].observations[0].frame_rate:"));
  text = text.replace(text.find("frame_rate: 100, "), 17, "");
  EXPECT_THAT(Error(text), HasSubstr(":13: cases[0].observations[0].drop:"));
}

TEST_F(MarkerSequencesTest, BadSequenceKeys) {
  ExpectError(With("drop: 0.1", "drop: 1.0"), 13, "cases[0].observations[0].drop");
  ExpectError(With("drop: 0.1", "drop: -0.1"), 13, "cases[0].observations[0].drop");
  ExpectError(With("frame_rate: 100", "frame_rate: 0"), 13, "cases[0].observations[0].frame_rate");
  ExpectError(With("frame_rate: 100", "frame_rate: fast"), 13,
              "cases[0].observations[0].frame_rate");
  ExpectError(With("drop: 0.1", "outliers: 0.1"), 13, "cases[0].observations[0].outliers");
  // A moving scene is observed by sequences of centre-line observations only.
  ExpectError(With("type: markers3d", "type: images"), 13, "cases[0].observations[0].type");
  // Its fit is plain least squares.
  ExpectError(With("cases:\n", "fit: {loss: huber}\ncases:\n"), 8, "fit.loss");
  ExpectError(With("cases:\n", "fit: {global: true}\ncases:\n"), 8, "fit.global");
}

TEST_F(MarkerSequencesTest, ReadsFramesAndMissingSamples) {
  dir_.Write("seq.csv",
             "frame,s,x,y,z\n"
             "0,0.1,0.1,0,0\n"
             "0,0.2,0.2,0,0\n"
             "1,0.1,0.1,0,-0.001\n"
             "1,0.2,,,\n"            // not seen
             "2,0.2,nan,NaN,nan\n"   // not seen
             "2,0.1,0.1,0,-0.002\n");
  const Experiment ex = LoadExperiment(dir_.Write("scene.yaml", kMoving));
  const SequenceInput input = BuildSequenceInput(ex);
  ASSERT_EQ(input.sequences.size(), 1u);
  const ObservationSequence& seq = input.sequences[0];
  EXPECT_EQ(seq.num_samples(), 4);
  ASSERT_EQ(seq.frames.size(), 3u);
  EXPECT_EQ(seq.frames[1].t, 0.01);
  EXPECT_EQ(seq.frames[2].t, 0.02);
  // Each frame is the static markers3d observation of the samples seen then, on the case's
  // vertices, numbered in the file's order.
  const auto* last = ModelOf<Markers3dObservation>(*seq.frames[2].measurement);
  ASSERT_NE(last, nullptr);
  EXPECT_EQ(last->sigma(), 5.0e-4);
  EXPECT_EQ(last->num_vertices(), 11);
  ASSERT_EQ(last->markers().size(), 1u);
  EXPECT_EQ(last->markers()[0].s, 0.1);
  EXPECT_EQ(last->markers()[0].p_world.z(), -0.002);
  EXPECT_EQ(seq.frames[0].sample, (std::vector<int>{0, 1}));
  EXPECT_EQ(seq.frames[2].sample, (std::vector<int>{3}));
  EXPECT_EQ(input.labels[0], "markers3d seq.csv");
}

TEST_F(MarkerSequencesTest, ReadsTimes) {
  dir_.Write("seq.csv", "t,s,x,y,z\n0.05,0.2,0.2,0,-0.01\n0,0.2,0.2,0,0\n");
  const Experiment ex = LoadExperiment(dir_.Write("scene.yaml", With("frame_rate: 100, ", "")));
  const ObservationSequence seq = BuildSequenceInput(ex).sequences.at(0);
  ASSERT_EQ(seq.frames.size(), 2u);
  EXPECT_EQ(seq.frames[0].t, 0.0);
  EXPECT_EQ(seq.frames[1].t, 0.05);
  EXPECT_EQ(seq.frames[1].sample, (std::vector<int>{0}));  // the file's first row is the later
}

// A t column read by an entry that also gives frame_rate: times that step by the rate are read
// as they are (with jitter and a dropped frame); a log stamped in milliseconds is an error that
// says so, naming the file's t column, instead of a run on times a thousand times too late.
TEST_F(MarkerSequencesTest, TimesMustAgreeWithTheEntrysFrameRate) {
  dir_.Write("seq.csv",
             "t,s,x,y,z\n0,0.2,0.2,0,0\n0.0102,0.2,0.2,0,0\n0.0199,0.2,0.2,0,0\n"
             "0.04,0.2,0.2,0,-0.001\n");
  const Experiment ex = LoadExperiment(dir_.Write("scene.yaml", kMoving));
  const ObservationSequence seq = BuildSequenceInput(ex).sequences.at(0);
  ASSERT_EQ(seq.frames.size(), 4u);
  EXPECT_EQ(seq.frames[3].t, 0.04);
  const std::string ms = "t,s,x,y,z\n0,0.2,0.2,0,0\n10,0.2,0.2,0,0\n20,0.2,0.2,0,0\n";
  ExpectCsvError(ms, 1, "t");
  EXPECT_THAT(Error(kMoving, ms), HasSubstr("median 10 s, but frame_rate 100 Hz"));
  EXPECT_THAT(Error(kMoving, ms), HasSubstr("t must be in seconds"));
}

TEST_F(MarkerSequencesTest, BadSequenceFiles) {
  const std::string no_rate = With("frame_rate: 100, ", "");
  ExpectCsvError("frame,s,x,y,z\n0,0.1,0.1,0,0\n", 1, "frame", no_rate);
  ExpectCsvError("s,x,y,z\n0.1,0.1,0,0\n", 1, "t");
  ExpectCsvError("t,s,x,y,z\n0,0.1,0.1,0,0\n0.2,0.1,0.1,0,0\n", 3, "t");  // beyond duration 0.1
  ExpectCsvError("t,s,x,y,z\n-0.01,0.1,0.1,0,0\n", 2, "t");
  ExpectCsvError("frame,s,x,y,z\n0.5,0.1,0.1,0,0\n", 2, "frame");
  ExpectCsvError("t,s,x,y,z\n0,0.3,0.1,0,0\n", 2, "s");                   // beyond L = 0.2
  ExpectCsvError("t,s,x,y,z\n0,0.1,0.1,0,0\n0,0.1,0.1,0,0\n", 3, "s");   // given twice
  ExpectCsvError("t,s,x,y,z\n0,0.1,0.1,,0\n", 2, "x");                   // partly missing
  ExpectCsvError("t,s,x,y,z\n0,0.1,0.1,zero,0\n", 2, "y");
  ExpectCsvError("t,s,x,y,z\n0,0.1,1e9,0,0\n", 2, "x");                  // not on the rod
  EXPECT_THAT(Error(kMoving, "t,s,x,y,z\n0,0.1,,,\n"), HasSubstr("no recorded sample"));
}

// Found by the fuzz corpus (tests/cli/fuzz_corpus_test.cc): a sample so many sigmas from the
// model that its squared residual overflows made the fit fail with an empty reason, or write a
// profile of nulls; the file's line and column are named instead.
TEST_F(MarkerSequencesTest, SamplesBeyondWhatAResidualHoldsAreRefused) {
  // A sigma of 1e-300 m: any point within reach of the rod is ~1e299 sigmas from it.
  ExpectCsvError("t,s,x,y,z\n0,0.1,0.1,0,0\n", 2, "x", With("sigma: 5.0e-4", "sigma: 1e-300"));
  const std::string log = With("{type: markers3d, file: seq.csv, sigma: 5.0e-4, s: [0.1, 0.2], "
                               "frame_rate: 100, drop: 0.1}",
                               "{type: reaction, file: seq.csv, point: clamp, sigma: 2.0e-6, "
                               "sigma_moment: 2.0e-7}");
  ExpectCsvError("t,fx,fy,fz,mx,my,mz\n0,0,0,-1e-4,0,1e-5,0\n0.01,0,1e308,0,0,0,0\n", 3, "fy",
                 log);
  ExpectCsvError("t,fx,fy,fz,mx,my,mz\n0,0,0,-1e-4,0,1e150,0\n", 2, "my", log);
  ExpectCsvError("t,fx,fy,fz,mx,my,mz\n0,0,0,-1e-4,1e-9,0,0\n", 2, "mx",
                 With("{type: markers3d, file: seq.csv, sigma: 5.0e-4, s: [0.1, 0.2], "
                      "frame_rate: 100, drop: 0.1}",
                      "{type: reaction, file: seq.csv, point: clamp, sigma: 2.0e-6, "
                      "sigma_moment: 1e-300}"));
  // The entry's line is named with its sigma.
  EXPECT_THAT(Error(log, "t,fx,fy,fz,mx,my,mz\n0,1e308,0,0,0,0,0\n"),
              HasSubstr("(sigma 2e-06, " + dir_.File("scene.yaml") + " line 13)"));
  // Large but within the bound: read (the fit then reports the misfit).
  dir_.Write("seq.csv", "t,fx,fy,fz,mx,my,mz\n0,1e20,0,0,0,0,0\n");
  EXPECT_NO_THROW(BuildSequenceInput(LoadExperiment(dir_.Write("scene.yaml", log))));
}

// Found by the fuzz corpus: the fit of a scene integrated by midpoint or explicit steps (which
// have no sensitivities) was refused without the line and key to change.
TEST_F(MarkerSequencesTest, AnIntegratorTheFitCannotDifferentiateNamesItsLine) {
  const std::string csv = "t,s,x,y,z\n0,0.1,0.1,0,0\n";
  for (const char* integrator : {"midpoint", "explicit"})
    EXPECT_THAT(Error(With("integrator: bdf2", std::string("integrator: ") + integrator), csv),
                HasSubstr(dir_.File("scene.yaml") + ":7: dynamics.integrator: the motion fit "
                          "differentiates the bdf2 and backward_euler steps, not " + integrator));
  // In block style the integrator's own line.
  const std::string block =
      With("dynamics: {time_step: 1.0e-3, duration: 0.1, integrator: bdf2}\n",
           "dynamics:\n  time_step: 1.0e-3\n  duration: 0.1\n  integrator: midpoint\n");
  EXPECT_THAT(Error(block, csv), HasSubstr(":10: dynamics.integrator:"));
  for (const char* integrator : {"bdf2", "backward_euler"})
    EXPECT_NO_THROW(BuildSequenceInput(LoadExperiment(dir_.Write(
        "scene.yaml", With("integrator: bdf2", std::string("integrator: ") + integrator)))));
}


// The same scene observed through a camera (tests/data/synth/cam_swing.yaml) and as 3-D points:
// each a sequence of the static models of image_points (with and without s) and points3d.
class PixelSequencesTest : public MarkerSequencesTest {
 protected:
  void SetUp() override {
    std::filesystem::copy_file(std::string(RODFIT_SOURCE_DIR) + "/tests/data/synth/cam_swing.yaml",
                               dir_.File("cam.yaml"));
  }
  // The experiment with line 13's entry replaced.
  static std::string Entry(const std::string& entry) {
    return With("{type: markers3d, file: seq.csv, sigma: 5.0e-4, s: [0.1, 0.2], frame_rate: 100, "
                "drop: 0.1}",
                entry);
  }
  static std::string Pixels(const std::string& rate = "frame_rate: 100, ") {
    return Entry("{type: image_points, file: seq.csv, camera: cam.yaml, sigma: 0.5, " + rate +
                 "drop: 0.1}");
  }
  ObservationSequence Read(const std::string& yaml, const std::string& csv, std::string* label) {
    dir_.Write("seq.csv", csv);
    const SequenceInput input = BuildSequenceInput(LoadExperiment(dir_.Write("scene.yaml", yaml)));
    EXPECT_EQ(input.sequences.size(), 1u);
    *label = input.labels.at(0);
    return input.sequences.at(0);
  }
};

TEST_F(PixelSequencesTest, ReadsPixelMarkersPerFrame) {
  std::string label;
  const ObservationSequence seq = Read(Pixels(),
                                       "frame,s,u,v\n"
                                       "0,0.2,973,511\n"
                                       "0,0.1,806,512\n"
                                       "1,0.2,,\n"        // not seen
                                       "1,0.1,nan,NaN\n"  // not seen
                                       "2,0.1,805,530\n",
                                       &label);
  EXPECT_EQ(label, "image_points seq.csv");
  ASSERT_EQ(seq.frames.size(), 2u);  // nothing seen in frame 1
  EXPECT_EQ(seq.frames[1].t, 0.02);
  EXPECT_EQ(seq.num_samples(), 3);
  const auto* first = ModelOf<ImageMarkersObservation>(*seq.frames[0].measurement);
  ASSERT_NE(first, nullptr);
  EXPECT_STREQ(first->unit(), "px");
  EXPECT_EQ(first->sigma(), 0.5);
  EXPECT_EQ(first->camera().K.fx, 1000.0);
  ASSERT_EQ(first->markers().size(), 2u);
  EXPECT_EQ(first->markers()[0].s, 0.2);
  EXPECT_EQ(first->markers()[1].uv, Eigen::Vector2d(806, 512));
  EXPECT_EQ(seq.frames[1].sample, (std::vector<int>{2}));
}

// Found by the fuzz corpus, as SamplesBeyondWhatAResidualHoldsAreRefused: pixels with a sigma
// so small that no residual can be squared.
TEST_F(PixelSequencesTest, PixelsBeyondWhatAResidualHoldsAreRefused) {
  ExpectCsvError("frame,s,u,v\n0,0.2,806,512\n", 2, "u",
                 Entry("{type: image_points, file: seq.csv, camera: cam.yaml, sigma: 1e-300, "
                       "frame_rate: 100}"));
  ExpectCsvError("t,u,v\n0,806,512\n", 2, "u",
                 Entry("{type: image_points, file: seq.csv, camera: cam.yaml, sigma: 1e-300}"));
}

TEST_F(PixelSequencesTest, ReadsCentreLinePixelsAndPoints) {
  std::string label;
  // Without s: closest-point pixels, several per frame; a t column.
  const ObservationSequence curve =
      Read(Pixels(""), "t,u,v\n0.05,700,540\n0,700,512\n0,800,512\n", &label);
  ASSERT_EQ(curve.frames.size(), 2u);
  const auto* at_0 = ModelOf<ImageCurveObservation>(*curve.frames[0].measurement);
  ASSERT_NE(at_0, nullptr);
  EXPECT_EQ(at_0->pixels().size(), 2u);
  EXPECT_EQ(at_0->num_noise_residuals(), 2);  // one per pixel: across the curve
  EXPECT_EQ(curve.frames[0].sample, (std::vector<int>{1, 2}));
  EXPECT_EQ(curve.frames[1].sample, (std::vector<int>{0}));
  // points3d: t,x,y,z.
  const ObservationSequence points =
      Read(Entry("{type: points3d, file: seq.csv, sigma: 1.0e-3}"),
           "t,x,y,z\n0,0.05,0,0\n0,0.1,0,0\n0.01,0.1,0,-0.001\n0.01,,,\n", &label);
  EXPECT_EQ(label, "points3d seq.csv");
  ASSERT_EQ(points.frames.size(), 2u);
  const auto* p = ModelOf<Points3dObservation>(*points.frames[1].measurement);
  ASSERT_NE(p, nullptr);
  ASSERT_EQ(p->samples().size(), 1u);
  EXPECT_EQ(p->samples()[0].z(), -0.001);
}

TEST_F(PixelSequencesTest, MovingSceneKeysOfPixelsAndPoints) {
  // image_points needs its camera; outliers are not part of a sequence.
  EXPECT_THAT(Error(Entry("{type: image_points, file: seq.csv, sigma: 0.5}")),
              HasSubstr(":13: cases[0].observations[0]"));
  EXPECT_THAT(Error(Entry("{type: image_points, file: seq.csv, camera: cam.yaml, sigma: 0.5, "
                          "outliers: 0.1}")),
              HasSubstr(":13: cases[0].observations[0].outliers:"));
  EXPECT_THAT(Error(Entry("{type: points3d, file: seq.csv, sigma: 1.0e-3, s: [0.1]}")),
              HasSubstr(":13: cases[0].observations[0].s:"));
}

TEST_F(PixelSequencesTest, BadPixelAndPointFiles) {
  const std::string pixels = Pixels();
  ExpectCsvError("s,u,v\n0.1,800,512\n", 1, "t", pixels);                 // no time
  EXPECT_THAT(Error(pixels, "frame,s,u\n0,0.1,800\n"),
              HasSubstr(dir_.File("seq.csv") + ": v: missing column"));
  ExpectCsvError("frame,s,u,v\n0,0.1,800,\n", 2, "u", pixels);            // partly missing
  ExpectCsvError("frame,s,u,v\n0,0.1,800,low\n", 2, "v", pixels);         // not a number
  ExpectCsvError("frame,s,u,v\n0,0.1,800,1e9\n", 2, "u", pixels);         // off the sensor
  ExpectCsvError("frame,s,u,v\n0,0.5,800,512\n", 2, "s", pixels);         // beyond L
  ExpectCsvError("frame,s,u,v\n0,0.1,800,512\n0,0.1,801,512\n", 3, "s", pixels);  // twice
  ExpectCsvError("frame,u,v\n0,800,512\n40,800,512\n", 3, "frame", pixels);  // after the run
  ExpectCsvError("frame,u,v\n-1,800,512\n", 2, "frame", pixels);
  EXPECT_THAT(Error(pixels, "frame,u,v\n0,,\n"), HasSubstr("no recorded sample"));
  const std::string points = Entry("{type: points3d, file: seq.csv, sigma: 1.0e-3}");
  ExpectCsvError("x,y,z\n0.1,0,0\n", 1, "t", points);
  ExpectCsvError("t,x,y,z\n0,0.1,0,\n", 2, "x", points);                  // partly missing
  ExpectCsvError("t,x,y,z\n0,100,0,0\n", 2, "x", points);                 // not on the rod
  ExpectCsvError("t,x,y,z\n0.5,0.1,0,0\n", 2, "t", points);               // after the run
}

}  // namespace
}  // namespace rodfit
