// Hostile input through the command line, the kinds this file covers: `fit` and
// `extract` that fail while writing leave every output (profile, report, points CSV, overlays)
// as it was; input files that are directories, devices, FIFOs or larger than the limit give one
// line naming them without being read; running out of memory is reported as such.
#include <sys/stat.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "../io/temp_dir.h"
#include "run_cli.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using test::ReadText;
using test::RunResult;
using test::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// A sagging thread with markers and one camera's image: enough for a quick fit with a report
// (one plot per camera) and for `extract`.
const char* const kExperiment =
    "rod: {length: 0.2, segments: 10, radius: 2.5e-4, linear_density: 5.6e-5}\n"
    "parameters:\n"
    "  bend_stiffness: {value: 1.0e-5, fit: true}\n"
    "  twist_stiffness: {value: 8.0e-6}\n"
    "  stretch_stiffness: {value: 245}\n"
    "cases:\n"
    "  - name: sag\n"
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
    "    observations:\n"
    "      - {type: markers3d, file: m.csv, sigma: 3.0e-4, count: 5}\n"
    "      - {type: image_points, file: uv.csv, camera: cam_front.yaml, sigma: 0.5}\n"
    "      - {type: images, file: front.png, camera: cam_front.yaml, sigma: 0.5}\n";

class AtomicBoundedCliTest : public ::testing::Test {
 protected:
  RunResult Rodfit(const std::string& args) { return test::RunRodfit(dir_, args); }
  static std::string Q(const std::string& s) { return test::Quote(s); }

  // One line on stderr containing `expected`, a non-zero exit and no signal.
  static void ExpectOneLineError(const RunResult& run, const std::string& expected) {
    EXPECT_GT(run.status, 0) << run.err;
    EXPECT_THAT(run.err, StartsWith("rodfit"));
    EXPECT_THAT(run.err, HasSubstr(expected));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  }

  // The entries of a directory, by name.
  static std::vector<std::string> Entries(const std::string& dir) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    return names;
  }

  // kExperiment synthesized into DIR/data; returns DIR/data/experiment.yaml.
  std::string SynthesizedExperiment() {
    const std::string source = dir_.Write("in/experiment.yaml", kExperiment);
    fs::copy_file(RODFIT_SOURCE_DIR "/tests/data/synth/cam_front.yaml",
                  dir_.File("in/cam_front.yaml"));
    const RunResult run = Rodfit("synth " + Q(source) + " -o " + Q(dir_.File("data")));
    EXPECT_EQ(run.status, 0) << run.err;
    return dir_.File("data/experiment.yaml");
  }

  TempDir dir_;
};

TEST_F(AtomicBoundedCliTest, FitThatFailsToWriteLeavesProfileAndReportAsTheyWere) {
  const std::string experiment = SynthesizedExperiment();
  const std::string profile = dir_.Write("out/profile.json", "old profile\n");
  const std::string report = dir_.File("report");
  dir_.Write("report/summary.csv", "old summary\n");
  fs::create_directory(report + "/index.html");  // the report's last file cannot be written
  const std::vector<std::string> top = Entries(dir_.path());
  const std::string fit = "fit " + Q(experiment) + " --quiet --threads 1";

  RunResult run = Rodfit(fit + " -o " + Q(profile) + " --report " + Q(report));
  ExpectOneLineError(run, "index.html: exists and is not a file");
  EXPECT_EQ(ReadText(profile), "old profile\n");
  EXPECT_EQ(Entries(dir_.File("out")), std::vector<std::string>{"profile.json"});
  EXPECT_EQ(ReadText(report + "/summary.csv"), "old summary\n");
  EXPECT_EQ(Entries(report), (std::vector<std::string>{"index.html", "summary.csv"}));
  EXPECT_TRUE(fs::is_empty(report + "/index.html"));

  // The profile's folder cannot be made (a file is in the way): a new report is not left behind.
  const std::string blocked = dir_.Write("blocked", "a file\n");
  run = Rodfit(fit + " -o " + Q(blocked + "/profile.json") + " --report " +
               Q(dir_.File("new/report")));
  ExpectOneLineError(run, blocked + ": exists and is not a directory");
  EXPECT_EQ(ReadText(blocked), "a file\n");
  EXPECT_FALSE(fs::exists(dir_.File("new")));
  EXPECT_EQ(Entries(dir_.path()), [&] {
    std::vector<std::string> names = top;
    names.push_back("blocked");
    std::sort(names.begin(), names.end());
    return names;
  }());

  // Without the obstacle both are written, the old files replaced, nothing else left behind.
  fs::remove(report + "/index.html");
  run = Rodfit(fit + " -o " + Q(profile) + " --report " + Q(report));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(ReadText(profile), StartsWith("{"));
  EXPECT_EQ(Entries(dir_.File("out")), std::vector<std::string>{"profile.json"});
  EXPECT_THAT(ReadText(report + "/summary.csv"), StartsWith("case,observation,"));
  EXPECT_EQ(Entries(report), (std::vector<std::string>{"figures", "index.html", "residuals.csv",
                                                       "summary.csv"}));
  EXPECT_EQ(Entries(report + "/figures"),
            (std::vector<std::string>{"camera_sag_cam_front.svg", "cost.svg", "histogram.svg",
                                      "residuals_sag.svg", "shape_sag_xy.svg",
                                      "shape_sag_xz.svg"}));
}

TEST_F(AtomicBoundedCliTest, ExtractThatFailsToWriteLeavesEveryOutputAsItWas) {
  SynthesizedExperiment();
  const std::string extract = "extract " + Q(dir_.File("data/front.png")) + " --camera " +
                              Q(dir_.File("data/cam_front.yaml"));
  const std::string overlay = dir_.Write("overlays/front.png", "old overlay\n");
  const std::string csv = dir_.File("points/points.csv");
  fs::create_directories(csv);  // the CSV, committed last, cannot be written
  const std::vector<std::string> top = Entries(dir_.path());

  // The overlay's folder is committed first, then rolled back when the CSV fails.
  RunResult run = Rodfit(extract + " -o " + Q(csv) + " --overlay " + Q(overlay));
  ExpectOneLineError(run, "points.csv: exists and is not a file");
  EXPECT_EQ(ReadText(overlay), "old overlay\n");
  EXPECT_EQ(Entries(dir_.File("overlays")), std::vector<std::string>{"front.png"});
  EXPECT_TRUE(fs::is_empty(csv));
  EXPECT_EQ(Entries(dir_.File("points")), std::vector<std::string>{"points.csv"});
  // An overlay in a folder of its own making: the folder goes again.
  run = Rodfit(extract + " -o " + Q(csv) + " --overlay " + Q(dir_.File("new/sub/front.png")));
  ExpectOneLineError(run, "points.csv: exists and is not a file");
  EXPECT_EQ(Entries(dir_.path()), top);

  // The same file twice is refused before anything is written.
  run = Rodfit(extract + " -o " + Q(dir_.File("twice.png")) + " --overlay " +
               Q(dir_.File("twice.png")));
  ExpectOneLineError(run, "is given as two outputs");
  EXPECT_EQ(Entries(dir_.path()), top);

  fs::remove(csv);
  run = Rodfit(extract + " -o " + Q(csv) + " --overlay " + Q(overlay));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(ReadText(csv), StartsWith("u,v\n"));
  EXPECT_THAT(ReadText(overlay), StartsWith("\x89PNG"));
  EXPECT_EQ(Entries(dir_.File("overlays")), std::vector<std::string>{"front.png"});
  EXPECT_EQ(Entries(dir_.File("points")), std::vector<std::string>{"points.csv"});
  EXPECT_EQ(Entries(dir_.path()), top);
}

TEST_F(AtomicBoundedCliTest, InputsThatAreNotRegularFilesOrTooLargeGiveOneLine) {
  const std::string folder = dir_.File("folder");
  fs::create_directory(folder);
  const std::string fifo = dir_.File("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string big = dir_.Write("big", "");
  fs::resize_file(big, (std::uintmax_t{256} << 20) + 1);  // sparse, one byte past the limit
  const std::string profile = dir_.File("p.json");

  // As the experiment (neither blocks: the FIFO has no writer, /dev/zero never ends).
  for (const auto& [path, expected] :
       {std::pair<std::string, std::string>{folder, "is a directory, not a YAML file"},
        {fifo, "is not a regular file (a device, FIFO or socket); a YAML file must be a file"},
        {"/dev/zero", "is not a regular file"},
        {big, "is 268435457 bytes, too large for a YAML file (at most 4194304)"}}) {
    SCOPED_TRACE(path);
    const RunResult run = Rodfit("fit " + Q(path) + " -o " + Q(profile));
    ExpectOneLineError(run, path + ": " + expected);
  }
  // As an observation's data file.
  for (const std::string& path : {folder, fifo, std::string("/dev/zero"), big}) {
    SCOPED_TRACE(path);
    const std::string experiment =
        dir_.Write("exp.yaml", test::Replace(kExperiment, "file: m.csv", "file: " + path));
    const RunResult run = Rodfit("fit " + Q(experiment) + " -o " + Q(profile));
    ExpectOneLineError(run, path + ": ");
    EXPECT_THAT(run.err, HasSubstr("a CSV file"));
  }
  // As an image.
  for (const std::string& path : {folder, fifo, std::string("/dev/zero"), big}) {
    SCOPED_TRACE(path);
    const RunResult run = Rodfit("extract " + Q(path) + " --camera " +
                                 Q(RODFIT_SOURCE_DIR "/tests/data/synth/cam_front.yaml") +
                                 " -o " + Q(dir_.File("uv.csv")));
    ExpectOneLineError(run, path + ": ");
    EXPECT_THAT(run.err, HasSubstr("an image file"));
  }
  // As a camera file (its own reader, at most 1 MiB): the FIFO is not opened either.
  for (const std::string& path : {folder, fifo, std::string("/dev/zero")}) {
    SCOPED_TRACE(path);
    const RunResult run = Rodfit("extract " + Q(dir_.File("image.png")) + " --camera " + Q(path) +
                                 " -o " + Q(dir_.File("uv.csv")));
    ExpectOneLineError(run, path + ": cannot open file: not a regular file");
  }
  EXPECT_FALSE(fs::exists(profile));
  EXPECT_FALSE(fs::exists(dir_.File("uv.csv")));
}

TEST_F(AtomicBoundedCliTest, OutOfMemoryIsReportedAsSuch) {
  // A data file at the size limit (sparse, one 256 MiB line) read by a process allowed 512 MiB
  // of address space (enough to start, about 250 MiB): the reader's copies do not fit.
  const std::string experiment = dir_.Write("exp.yaml", kExperiment);
  const std::string data = dir_.Write("m.csv", "");
  fs::resize_file(data, std::uintmax_t{256} << 20);
  const std::string profile = dir_.File("p.json");
  const std::string out = dir_.File("stdout.txt"), err = dir_.File("stderr.txt");
  // Where the program cannot even start in that address space (other libraries, sanitizers),
  // there is nothing to test.
  if (std::system(("ulimit -v 524288 && '" RODFIT_CLI "' --version >" + Q(out) + " 2>&1").c_str()) !=
      0)
    GTEST_SKIP() << "rodfit does not start within 512 MiB of address space here";
  const int raw = std::system(("ulimit -v 524288 && '" RODFIT_CLI "' fit " + Q(experiment) +
                               " -o " + Q(profile) + " >" + Q(out) + " 2>" + Q(err))
                                  .c_str());
  RunResult run;
  run.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  run.err = ReadText(err);
  EXPECT_EQ(run.status, 1) << run.err;
  EXPECT_EQ(run.err, "rodfit: out of memory while running fit (inputs or limits too large for "
                     "this machine)\n");
  EXPECT_FALSE(fs::exists(profile));
}

}  // namespace
}  // namespace rodfit
