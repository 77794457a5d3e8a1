// Motion-capture recordings as mocap software exports them (io/recording.h, docs/formats.md
// "Recordings"): missing samples as nan or empty fields, jittered timestamps, a frame rate
// given with a t column, markers numbered out of order along the rod.
#include <cmath>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/temp_dir.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/recording.h"

namespace rodfit {
namespace {

using ::testing::HasSubstr;
using test::TempDir;

// Four markers along a gently curved rod, `frames` frames at 100 Hz, each time shifted by
// jitter(k) [s]; `cell(k, m)` replaces marker m's coordinates in frame k when not empty.
template <typename Jitter, typename Cell>
std::string Recording(int frames, Jitter jitter, Cell cell) {
  std::string csv = "t,marker,x,y,z\n";
  for (int k = 0; k < frames; ++k) {
    char t[64];
    std::snprintf(t, sizeof(t), "%.6f", 0.01 * k + jitter(k));
    for (int m = 0; m < 4; ++m) {
      std::string xyz = cell(k, m);
      if (xyz.empty()) {
        char p[128];
        std::snprintf(p, sizeof(p), "%.6f,%.6f,%.6f", 0.3 * m, 0.001 * k, -0.02 * m * m);
        xyz = p;
      }
      csv += std::string(t) + "," + std::to_string(m) + "," + xyz + "\n";
    }
  }
  return csv;
}

std::string ErrorOf(const std::string& path, double frame_rate = 0.0) {
  try {
    ReadMarkerRecording(path, frame_rate);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

auto kNoJitter = [](int) { return 0.0; };
auto kAsIs = [](int, int) { return std::string(); };

TEST(Recording, NanAndEmptyFieldsAreSamplesNotSeen) {
  TempDir dir;
  const std::string path = dir.Write("r.csv", Recording(5, kNoJitter, [](int k, int m) {
    if (k == 2 && m == 1) return std::string("nan,nan,nan");
    if (k == 3 && m == 2) return std::string("NaN,NaN,NaN");
    if (k == 4 && m == 3) return std::string(",,");
    return std::string();
  }));
  const MarkerRecording rec = ReadMarkerRecording(path, 0.0);
  ASSERT_EQ(rec.frames.size(), 5u);
  EXPECT_DOUBLE_EQ(rec.frame_interval, 0.01);
  EXPECT_FALSE(rec.frames[2].col(1).allFinite());
  EXPECT_FALSE(rec.frames[3].col(2).allFinite());
  EXPECT_FALSE(rec.frames[4].col(3).allFinite());
  EXPECT_TRUE(rec.frames[4].col(2).allFinite());
  EXPECT_DOUBLE_EQ(rec.frames[4](0, 2), 0.6);
  // Text that is neither a number nor a missing sample is still an error, with its line.
  const std::string bad = dir.Write("b.csv", Recording(3, kNoJitter, [](int k, int m) {
    return k == 1 && m == 0 ? std::string("0,abc,0") : std::string();
  }));
  EXPECT_THAT(ErrorOf(bad), HasSubstr("b.csv:6: y: not a number: 'abc'"));
  // A marker given twice in one frame, once as nan, is still given twice.
  const std::string twice =
      dir.Write("d.csv", Recording(3, kNoJitter, kAsIs) + "0.01,1,nan,nan,nan\n");
  EXPECT_THAT(ErrorOf(twice), HasSubstr("given twice in one frame"));
}

// One row per frame, x0,y0,z0,x1,... (wide, as motion-capture software exports): the same
// recording as the long form, capitalised headers and missing samples included.
TEST(Recording, WideFormIsTheLongFormOneRowPerFrame) {
  TempDir dir;
  const std::string long_path = dir.Write("long.csv", Recording(5, kNoJitter, [](int k, int m) {
    return k == 3 && m == 2 ? std::string("nan,nan,nan") : std::string();
  }));
  std::string wide = "Frame,X0,Y0,Z0,X1,Y1,Z1,X2,Y2,Z2,X3,Y3,Z3\n";
  for (int k = 0; k < 5; ++k) {
    wide += std::to_string(k);
    for (int m = 0; m < 4; ++m) {
      char p[128];
      if (k == 3 && m == 2)
        std::snprintf(p, sizeof(p), ",,,");
      else
        std::snprintf(p, sizeof(p), ",%.6f,%.6f,%.6f", 0.3 * m, 0.001 * k, -0.02 * m * m);
      wide += p;
    }
    wide += "\n";
  }
  const std::string wide_path = dir.Write("wide.csv", wide);
  const MarkerRecording a = ReadMarkerRecording(long_path, 0.0);
  const MarkerRecording b = ReadMarkerRecording(wide_path, 100.0);
  ASSERT_EQ(b.frames.size(), a.frames.size());
  EXPECT_DOUBLE_EQ(b.frame_interval, a.frame_interval);
  for (size_t k = 0; k < a.frames.size(); ++k) {
    ASSERT_EQ(b.frames[k].cols(), 4);
    for (int m = 0; m < 4; ++m) {
      EXPECT_EQ(b.frames[k].col(m).allFinite(), a.frames[k].col(m).allFinite());
      if (a.frames[k].col(m).allFinite()) {
        EXPECT_EQ(b.frames[k].col(m), a.frames[k].col(m));
      }
    }
  }
  // A marker without its z, a frame given twice and a bad number, each at its line and column.
  const std::string no_z = dir.Write("nz.csv", "t,x0,y0,z0,x1,y1\n0,0,0,0,1,0\n");
  EXPECT_THAT(ErrorOf(no_z), HasSubstr("nz.csv: z1: missing column"));
  const std::string twice = dir.Write("tw.csv", "frame,x0,y0,z0\n0,0,0,0\n0,1,0,0\n");
  EXPECT_THAT(ErrorOf(twice, 100.0), HasSubstr("tw.csv:3: frame: this frame is given twice"));
  const std::string bad = dir.Write("bd.csv", "frame,x0,y0,z0\n0,0,0,0\n1,0,q,0\n");
  EXPECT_THAT(ErrorOf(bad, 100.0), HasSubstr("bd.csv:3: y0: not a number: 'q'"));
}

TEST(Recording, JitteredTimesAreTakenAtTheirNominalFrames) {
  TempDir dir;
  // 0.3 ms of jitter at 100 Hz, alternating, as a mocap clock might stamp frames.
  const std::string path = dir.Write("j.csv", Recording(
      40, [](int k) { return k == 0 ? 0.0 : (k % 2 ? 3e-4 : -2e-4) * std::sin(0.7 * k); }, kAsIs));
  const MarkerRecording rec = ReadMarkerRecording(path, 0.0);
  ASSERT_EQ(rec.frames.size(), 40u);
  EXPECT_DOUBLE_EQ(rec.frame_interval, 0.01);  // 100 Hz exactly: the rollout's step divides it
  for (int k = 0; k < 40; ++k) EXPECT_NEAR(rec.frames[k](1, 0), 0.001 * k, 1e-12) << k;
  // A whole frame missing is a dropped frame, not irregular sampling.
  std::string dropped = "t,marker,x,y,z\n";
  for (int k : {0, 1, 2, 4, 5}) dropped += std::to_string(0.01 * k) + ",0,0,0," + std::to_string(k) + "\n";
  const MarkerRecording d = ReadMarkerRecording(dir.Write("d.csv", dropped), 0.0);
  ASSERT_EQ(d.frames.size(), 6u);
  EXPECT_FALSE(d.frames[3].allFinite());
  EXPECT_DOUBLE_EQ(d.frames[5](2, 0), 5.0);
}

TEST(Recording, IrregularTimesAreRefusedWithTheirLine) {
  TempDir dir;
  // Frame 5 stamped 4 ms late (40 % of the interval): a gap, not jitter.
  const std::string late = dir.Write("late.csv", Recording(
      10, [](int k) { return k == 5 ? 4e-3 : 0.0; }, kAsIs));
  EXPECT_THAT(ErrorOf(late), HasSubstr("late.csv:22: t: irregular sampling"));
  // One and a half frame intervals between two times.
  const std::string half = dir.Write(
      "half.csv", "t,marker,x,y,z\n0,0,0,0,0\n0.01,0,0,0,1\n0.02,0,0,0,2\n0.035,0,0,0,3\n0.045,0,0,0,4\n");
  EXPECT_THAT(ErrorOf(half), HasSubstr("half.csv:5: t: irregular sampling"));
}

TEST(Recording, FrameRateWithATimeColumnMustAgree) {
  TempDir dir;
  const std::string path = dir.Write("r.csv", Recording(5, kNoJitter, kAsIs));
  EXPECT_DOUBLE_EQ(ReadMarkerRecording(path, 100.0).frame_interval, 0.01);
  EXPECT_THAT(ErrorOf(path, 120.0),
              HasSubstr("r.csv:1: t: --frame-rate 120 Hz disagrees with the times of the t column (100 Hz)"));
}

TEST(Recording, MarkersOutOfOrderAlongTheRodAreSaid) {
  TempDir dir;
  // Markers 1 and 2 swapped: the label-order line folds back at both.
  const std::string swapped = dir.Write("s.csv", Recording(3, kNoJitter, [](int k, int m) {
    const int place = m == 1 ? 2 : m == 2 ? 1 : m;
    char p[128];
    std::snprintf(p, sizeof(p), "%.6f,%.6f,%.6f", 0.3 * place, 0.001 * k, -0.02 * place * place);
    return std::string(p);
  }));
  EXPECT_THAT(ErrorOf(swapped), HasSubstr("s.csv: marker: markers out of order along the rod: in frame 0 the line "
                                      "through markers 0, 1, 2 folds back"));
  // Eight markers along a rising arc, labelled 0, 2, 4, 6, 1, 3, 5, 7 along it: no turn of
  // the label-order line reaches 150 degrees (144 at most), but it is 2.3 times as long as the
  // nearest-neighbour path.
  std::string shuffled = "t,marker,x,y,z\n";
  const int place[8] = {0, 2, 4, 6, 1, 3, 5, 7};
  for (int k = 0; k < 2; ++k)
    for (int m = 0; m < 8; ++m) {
      const double a = M_PI * place[m] / 7.0;
      shuffled += std::to_string(0.01 * k) + "," + std::to_string(m) + "," +
                  std::to_string(0.3 * std::sin(a)) + "," + std::to_string(0.3 * (1 - std::cos(a))) +
                  "," + std::to_string(0.05 * place[m]) + "\n";
    }
  EXPECT_THAT(ErrorOf(dir.Write("sh.csv", shuffled)),
              HasSubstr("sh.csv: marker: markers out of order along the rod: in frame 0 the line "
                        "through them in label order is"));
  // A cable bent into a U (markers in order) is fine.
  std::string u = "t,marker,x,y,z\n";
  for (int k = 0; k < 2; ++k)
    for (int m = 0; m < 9; ++m) {
      const double a = M_PI * m / 8.0;
      u += std::to_string(0.01 * k) + "," + std::to_string(m) + "," + std::to_string(0.2 * std::sin(a)) +
           "," + std::to_string(0.2 * (1 - std::cos(a))) + ",0\n";
    }
  EXPECT_NO_THROW(ReadMarkerRecording(dir.Write("u.csv", u), 0.0));
}

// Issue 34: jitter alternating +-9 % of the interval (inside the documented 10 %) put every
// difference 18 % off and the median with them, and was refused with a wrong interval.
TEST(Recording, AlternatingJitterWithinTenPercentIsAccepted) {
  TempDir dir;
  const std::string path = dir.Write("alt.csv", Recording(
      30, [](int k) { return k == 0 ? 0.0 : (k % 2 ? 9e-4 : -9e-4); }, kAsIs));
  const MarkerRecording rec = ReadMarkerRecording(path, 0.0);
  ASSERT_EQ(rec.frames.size(), 30u);
  EXPECT_NEAR(rec.frame_interval, 0.01, 1e-4);
  for (int k = 0; k < 30; ++k) EXPECT_NEAR(rec.frames[k](1, 0), 0.001 * k, 1e-12) << k;  // Over few frames, frame 0 on time: the least-squares line misses the bound; the recording is
  // within it all the same.
  std::string few = "t,marker,x,y,z\n";
  for (int k = 0; k <= 10; ++k) {
    char row[96];
    std::snprintf(row, sizeof(row), "%.6f,0,0,0,%d\n", 0.01 * k + (k == 0 ? 0.0 : k % 2 ? 9e-4 : -9e-4), k);
    few += row;
  }
  const MarkerRecording f = ReadMarkerRecording(dir.Write("few.csv", few), 0.0);
  ASSERT_EQ(f.frames.size(), 11u);
  EXPECT_DOUBLE_EQ(f.frame_interval, 0.01);
  EXPECT_DOUBLE_EQ(f.frames[10](2, 0), 10.0);
}

// Issue 34: a recording stamped in milliseconds read as seconds ran for minutes with no output.
TEST(Recording, AFrameIntervalAboveOneSecondIsRefused) {
  TempDir dir;
  std::string ms = "t,marker,x,y,z\n";
  for (int k = 0; k < 5; ++k)
    for (int m = 0; m < 2; ++m) ms += std::to_string(10 * k) + "," + std::to_string(m) + "," + std::to_string(0.3 * m) + ",0,0\n";
  EXPECT_THAT(ErrorOf(dir.Write("ms.csv", ms)),
              HasSubstr("ms.csv:2: t: the frames are 10 s apart, more than 1 s: times in milliseconds?"));
  EXPECT_THAT(ErrorOf(dir.Write("f.csv", "frame,marker,x,y,z\n0,0,0,0,0\n1,0,0,0,1\n"), 0.5),
              HasSubstr("f.csv:1: frame: --frame-rate 0.5 Hz puts the frames 2 s apart"));
}

// Issue 34: a .csv.gz recording gave "expected 1 fields as in the header, got 2".
TEST(Recording, AGzipFileIsNamedAsSuch) {
  TempDir dir;
  const std::string path = dir.Write("r.csv.gz", std::string("\x1f\x8b\x08\x00garbage,\n1,2\n", 16));
  EXPECT_THAT(ErrorOf(path), HasSubstr("r.csv.gz: is gzip-compressed; decompress it first"));
}

// Issue 34: rollout accepted a recording of another rod (scaled 1.5 times: the rod stretched
// 49 % between its held markers).
TEST(Recording, ARecordingOfAnotherRodIsRefused) {
  TempDir dir;
  // The four markers' polyline in frame 0: 0.9 m and a little (the gentle curve).
  const MarkerRecording rec = ReadMarkerRecording(dir.Write("r.csv", Recording(5, kNoJitter, kAsIs)), 0.0);
  EXPECT_NO_THROW(CheckRecordingFitsRod(rec, 0.95));
  EXPECT_NO_THROW(CheckRecordingFitsRod(rec, 1.1));
  auto error = [&](const MarkerRecording& r, double length) -> std::string {
    try {
      CheckRecordingFitsRod(r, length);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_THAT(error(rec, 0.6), HasSubstr("r.csv: frame 0: the markers' polyline is"));
  EXPECT_THAT(error(rec, 1.5), HasSubstr("r.csv: frame 0: the markers' polyline is"));
  // A later frame stretched to 1.5 times: refused at that frame.
  MarkerRecording stretched = rec;
  stretched.frames[3] *= 1.5;
  EXPECT_THAT(error(stretched, 0.95), HasSubstr("r.csv: frame 3: the markers' polyline is"));
}

// A motion fit's rest shape (motion_fit.json's rest_shape, written by rollout --fit
// rest_curvature) read back as a rest-curvature profile; a file without one gives none; lists
// of other lengths, non-numbers or knots beyond the rod are one error naming the file and key.
TEST(Recording, MotionFitRestShapeIsReadAsAProfile) {
  TempDir dir;
  std::vector<double> s;
  std::vector<Eigen::Vector3d> k;
  const std::string good = dir.Write(
      "m.json", "{\"parameters\": {}, \"rest_shape\": {\"s_m\": [0, 0.5, 1], \"k1_per_m\": "
                "[1, 2, 3], \"k2_per_m\": [-1, 0, 0.5], \"tau_per_m\": [0, 0, 0]}}");
  ASSERT_TRUE(ReadMotionFitRestShape(good, 1.0, &s, &k));
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[1], 0.5);
  EXPECT_EQ(k[2], Eigen::Vector3d(3, 0.5, 0));
  EXPECT_TRUE(ReadMotionFitValues(good).empty());  // a rest shape alone is a fit's result
  const std::string none = dir.Write("n.json", "{\"parameters\": {\"damping\": {\"value\": 1}}}");
  EXPECT_FALSE(ReadMotionFitRestShape(none, 1.0, &s, &k));
  const std::string shorter = dir.Write(
      "b.json", "{\"parameters\": {},\n\"rest_shape\": {\"s_m\": [0, 1], \"k1_per_m\": [1], "
                "\"k2_per_m\": [1, 2], \"tau_per_m\": [0, 0]}}");
  try {
    ReadMotionFitRestShape(shorter, 1.0, &s, &k);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("b.json:2: rest_shape: s_m, k1_per_m"));
  }
  const std::string beyond = dir.Write(
      "c.json", "{\"rest_shape\": {\"s_m\": [0, 2], \"k1_per_m\": [1, 1], "
                "\"k2_per_m\": [1, 2], \"tau_per_m\": [0, 0]}}");
  try {
    ReadMotionFitRestShape(beyond, 1.0, &s, &k);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("c.json:1: rest_shape.s_m: must increase strictly"));
  }
}

}  // namespace
}  // namespace rodfit
