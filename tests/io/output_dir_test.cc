// Output directories (io/output_dir.h): names never leave their directory, no output
// is one of the run's inputs, and a staged directory appears whole or not at all, a failure
// leaving an existing one as it was.
#include "rodfit/io/output_dir.h"

#include <sys/stat.h>

#include <filesystem>
#include <iterator>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/errors.h"
#include "temp_dir.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using test::ReadText;
using test::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

TEST(OutputDir, OutputNamesStayInsideTheirDirectory) {
  EXPECT_EQ(PathInside("/out", "a.obj", "case file name"), "/out/a.obj");
  EXPECT_EQ(PathInside("/out", "sub/a.csv", "file"), "/out/sub/a.csv");
  for (const std::string& name : {std::string("../x.obj"), std::string("/etc/passwd"),
                                  std::string("a/../../x"), std::string(""), std::string("."),
                                  std::string("a\\b"), std::string("a\0b", 3)}) {
    SCOPED_TRACE(name);
    try {
      PathInside("/out", name, "case file name");
      ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), StartsWith("/out: case file name '"));
    }
  }
}

TEST(OutputDir, AnOutputThatIsAnInputIsRefused) {
  TempDir dir;
  const std::string experiment = dir.Write("exp/experiment.yaml", "x: 1\n");
  const std::string data = dir.Write("exp/m.csv", "s,x,y,z\n");
  const std::vector<InputFile> inputs = {{experiment, "the experiment"},
                                         {data, "the data file of cases[0].observations[0]"}};
  // The same file by another spelling, and through a symbolic link.
  fs::create_directory_symlink(dir.File("exp"), dir.File("link"));
  for (const std::string& output :
       {dir.File("exp/./experiment.yaml"), dir.File("exp/../exp/m.csv"), dir.File("link/m.csv")}) {
    SCOPED_TRACE(output);
    try {
      RefuseOverwritingInput(output, inputs);
      ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_THAT(message, StartsWith(output + ": is the "));
      EXPECT_THAT(message, HasSubstr("an input of this run"));
    }
  }
  EXPECT_NO_THROW(RefuseOverwritingInput(dir.File("exp/profile.json"), inputs));
  EXPECT_EQ(ReadText(experiment), "x: 1\n");
}

TEST(OutputDir, StagedDirectoryAppearsWholeOrNotAtAll) {
  TempDir dir;
  const std::string target = dir.File("new/out");
  {
    StagedDirectory out(target);
    out.Write("a.csv", "a\n");
    out.Write("sub/b.csv", "b\n");
    EXPECT_FALSE(fs::exists(target));  // nothing visible before Commit
    // Dropped without Commit (a failed run): the staging and the parent it made are gone.
  }
  EXPECT_FALSE(fs::exists(dir.File("new")));
  EXPECT_TRUE(fs::is_empty(dir.path()));
  {
    StagedDirectory out(target);
    out.Write("a.csv", "a\n");
    out.Write("sub/b.csv", "b\n");
    out.Commit();
  }
  EXPECT_EQ(ReadText(target + "/a.csv"), "a\n");
  EXPECT_EQ(ReadText(target + "/sub/b.csv"), "b\n");
  // Only the target is left beside it: no staging directory.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.File("new")), fs::directory_iterator()), 1);
}

TEST(OutputDir, StagedDirectoryIntoAnExistingOneLeavesItAsItWasOnFailure) {
  TempDir dir;
  const std::string target = dir.File("out");
  dir.Write("out/a.csv", "old a\n");
  dir.Write("out/keep.txt", "mine\n");
  fs::create_directory(dir.File("out/c.obj"));  // a directory where a file goes
  {
    StagedDirectory out(target);
    out.Write("a.csv", "new a\n");
    out.Write("b.csv", "new b\n");
    out.Write("c.obj", "new c\n");
    try {
      out.Commit();
      ADD_FAILURE() << "committed over a directory";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("c.obj: exists and is not a file"));
    }
  }
  EXPECT_EQ(ReadText(target + "/a.csv"), "old a\n");
  EXPECT_FALSE(fs::exists(target + "/b.csv"));
  EXPECT_TRUE(fs::is_directory(target + "/c.obj"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);

  // Without the obstacle: replaced and added, the user's other files untouched.
  fs::remove(dir.File("out/c.obj"));
  StagedDirectory out(target);
  out.Write("a.csv", "new a\n");
  out.Write("c.obj", "new c\n");
  out.Commit();
  EXPECT_EQ(ReadText(target + "/a.csv"), "new a\n");
  EXPECT_EQ(ReadText(target + "/c.obj"), "new c\n");
  EXPECT_EQ(ReadText(target + "/keep.txt"), "mine\n");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

TEST(OutputDir, StagedDirectoryRefusesAFileAsTarget) {
  TempDir dir;
  const std::string file = dir.Write("out", "a file\n");
  try {
    StagedDirectory out(file);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), file + ": exists and is not a directory");
  }
  EXPECT_EQ(ReadText(file), "a file\n");
}

TEST(OutputDir, CommitAllRollsBackTheOutputsAlreadyCommittedWhenALaterOneFails) {
  TempDir dir;
  dir.Write("report/summary.csv", "old summary\n");
  dir.Write("report/keep.txt", "mine\n");
  dir.Write("profile/profile.json", "old profile\n");
  {
    StagedDirectory report(dir.File("report")), fresh(dir.File("new/fresh"));
    StagedDirectory profile(dir.File("profile"), /*stage_inside=*/true);
    report.Write("summary.csv", "new summary\n");
    report.Write("residuals.csv", "new residuals\n");
    fresh.Write("a.csv", "a\n");
    profile.Write("profile.json", "new profile\n");
    // The last output cannot be committed: a directory appeared where its file goes.
    fs::remove(dir.File("profile/profile.json"));
    fs::create_directory(dir.File("profile/profile.json"));
    try {
      CommitAll({&report, &fresh, &profile});
      ADD_FAILURE() << "committed over a directory";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("profile.json: exists and is not a file"));
    }
    // Rolled back at once, not only when the objects go.
    EXPECT_EQ(ReadText(dir.File("report/summary.csv")), "old summary\n");
    EXPECT_FALSE(fs::exists(dir.File("report/residuals.csv")));
    EXPECT_FALSE(fs::exists(dir.File("new")));
  }
  EXPECT_EQ(ReadText(dir.File("report/keep.txt")), "mine\n");
  EXPECT_TRUE(fs::is_empty(dir.File("profile/profile.json")));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.File("report")), fs::directory_iterator()), 2);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.File("profile")), fs::directory_iterator()), 1);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 2);

  // Without the obstacle all are committed, and nothing but the outputs is left.
  fs::remove(dir.File("profile/profile.json"));
  {
    StagedDirectory report(dir.File("report")), fresh(dir.File("new/fresh"));
    StagedDirectory profile(dir.File("profile"), /*stage_inside=*/true);
    report.Write("summary.csv", "new summary\n");
    fresh.Write("a.csv", "a\n");
    profile.Write("profile.json", "new profile\n");
    CommitAll({&report, &fresh, &profile});
    EXPECT_EQ(ReadText(dir.File("report/summary.csv")), "new summary\n");
    EXPECT_EQ(ReadText(dir.File("new/fresh/a.csv")), "a\n");
    EXPECT_EQ(ReadText(dir.File("profile/profile.json")), "new profile\n");
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.File("profile")), fs::directory_iterator()),
              1);
  }
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 3);
}

// Issue 34: one output rule for every command and writer: never an empty path, never over a
// device, FIFO or directory, never over an input; StagedDirectory keeps it for every file.
TEST(OutputDir, CheckOutputFileRefusesEmptyNonRegularAndInputs) {
  TempDir dir;
  const std::string input = dir.Write("in.csv", "t,x,y,z\n");
  const std::vector<InputFile> inputs = {{input, "the drive path of cases[0] (end_pin)"}};
  auto error = [&](const std::string& path) -> std::string {
    try {
      CheckOutputFile(path, inputs);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_THAT(error(""), HasSubstr("the output path is empty"));
  EXPECT_THAT(error("/dev/null"), HasSubstr("/dev/null: exists and is not a file"));
  ASSERT_EQ(::mkfifo(dir.File("fifo").c_str(), 0600), 0);
  EXPECT_THAT(error(dir.File("fifo")), HasSubstr("exists and is not a file"));
  fs::create_directory(dir.File("d"));
  EXPECT_THAT(error(dir.File("d")), HasSubstr("exists and is not a file (a directory)"));
  EXPECT_THAT(error(input), HasSubstr("is the drive path of cases[0] (end_pin)"));
  EXPECT_EQ(error(dir.File("new.csv")), "");
  // A staged directory with the run's inputs refuses to stage over one, and its commit keeps
  // the rule for what appeared since.
  {
    StagedDirectory out(dir.path());
    out.SetInputs(inputs);
    EXPECT_THROW(out.Write("in.csv", "x"), InputError);
    out.Write("later.csv", "x");
    ASSERT_EQ(::mkfifo(dir.File("later.csv").c_str(), 0600), 0);
    EXPECT_THROW(out.Commit(), InputError);
  }
  EXPECT_TRUE(fs::is_fifo(dir.File("later.csv")));
  EXPECT_EQ(ReadText(input), "t,x,y,z\n");
  EXPECT_THROW(StagedDirectory(""), InputError);
  EXPECT_THROW(CheckOutputDirectory("", {"a.csv"}, {}), InputError);
  EXPECT_THROW(CheckOutputDirectory(dir.path(), {"in.csv"}, inputs), InputError);
  EXPECT_NO_THROW(CheckOutputDirectory(dir.path(), {"out.csv"}, inputs));
}

}  // namespace
}  // namespace rodfit
