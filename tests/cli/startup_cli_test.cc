// The CLI's two parts (docs/cli.md, "Start-up"): the `rodfit` executable alone, copied where its
// commands module is not, still runs --help, --version, simulate (static and moving scenes) and
// export, and loads neither Ceres nor OpenCV nor their dependencies; the module's commands then
// fail with one line naming the missing (or broken) module, exit 1.
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "../io/temp_dir.h"
#include "run_cli.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using test::Quote;
using test::ReadText;
using test::RunResult;
using ::testing::HasSubstr;
using ::testing::StartsWith;

class StartupCliTest : public ::testing::Test {
 protected:
  StartupCliTest() {
    fs::create_directories(dir_.File("bin"));
    fs::copy_file(RODFIT_CLI, alone_);
  }

  // `ENV bin/rodfit ARGS`, the executable without its module.
  RunResult Alone(const std::string& args, const std::string& env = "") const {
    const std::string out = dir_.File("stdout.txt"), err = dir_.File("stderr.txt");
    const int raw = std::system(
        (env + " " + Quote(alone_) + " " + args + " >" + Quote(out) + " 2>" + Quote(err)).c_str());
    RunResult run;
    run.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    run.out = ReadText(out);
    run.err = ReadText(err);
    return run;
  }

  static std::string Bundled(const std::string& path) {
    return Quote(std::string(RODFIT_SOURCE_DIR) + "/" + path);
  }

  test::TempDir dir_;
  const std::string alone_ = dir_.File("bin/rodfit");
};

TEST_F(StartupCliTest, ExecutableAloneRunsItsOwnCommands) {
  RunResult run = Alone("--help");
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("fit "));  // the module's commands are listed without it
  run = Alone("--version");
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.out, StartsWith("rodfit "));

  run = Alone("simulate " + Bundled("data/scenes/cantilever.yaml") + " -o " +
              Quote(dir_.File("static")));
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir_.File("static/shapes.csv")));
  run = Alone("simulate " + Bundled("data/scenes/suture_swing.yaml") + " -o " +
              Quote(dir_.File("moving")));
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir_.File("moving/trajectory.csv")));
  run = Alone("export " + Bundled("data/profiles/suture.json") + " --format json -o " +
              Quote(dir_.File("suture.json")));
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir_.File("suture.json")));
}

TEST_F(StartupCliTest, ExecutableLoadsNeitherCeresNorOpenCV) {
  // glibc's loader lists the shared objects a program needs, and exits, when this is set (what
  // ldd does).
  const RunResult run = Alone("--help", "LD_TRACE_LOADED_OBJECTS=1");
  if (run.out.find("libc.so") == std::string::npos)
    GTEST_SKIP() << "the dynamic loader here does not list a program's libraries";
  for (const char* heavy : {"ceres", "opencv", "glog", "gflags", "cholmod", "tbb", "lapack",
                            "nlopt", "libX11", "libGL"})
    EXPECT_THAT(run.out, ::testing::Not(HasSubstr(heavy))) << run.out;
}

TEST_F(StartupCliTest, ModuleCommandWithoutModuleIsOneLine) {
  for (const char* command : {"synth", "extract", "fit", "rollout", "bench"}) {
    SCOPED_TRACE(command);
    const RunResult run = Alone(std::string(command) + " --help");
    EXPECT_EQ(run.status, 1);
    EXPECT_THAT(run.err, StartsWith(std::string("rodfit: ") + command +
                                    " needs the commands module rodfit-commands.so, which is "
                                    "neither in " + dir_.File("bin") + " nor in "));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    EXPECT_EQ(run.out, "");
  }
}

TEST_F(StartupCliTest, BrokenModuleIsOneLine) {
  dir_.Write("bin/rodfit-commands.so", "not a shared object\n");
  const RunResult run = Alone("fit --help");
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, StartsWith("rodfit: cannot load " + dir_.File("bin/rodfit-commands.so") +
                                  " for fit: "));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
}

TEST_F(StartupCliTest, ModuleBesideTheExecutableIsUsed) {
  fs::copy_file(fs::path(RODFIT_CLI).parent_path() / "rodfit-commands.so",
                dir_.File("bin/rodfit-commands.so"));
  const RunResult run = Alone("fit --help");
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("profile JSON"));
}

}  // namespace
}  // namespace rodfit
