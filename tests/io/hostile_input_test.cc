// Hostile input at the io layer: case names that would be paths are refused where they
// are read, and echoed values are cut short, so a 1 MiB field makes a short message.
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "temp_dir.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::EndsWith;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const char* const kScene =
    "rod: {length: 0.2, segments: 10, radius: 1.0e-4, linear_density: 5.0e-5}\n"  // 1
    "parameters:\n"                                                                 // 2
    "  bend_stiffness: {value: 1.0e-6}\n"                                           // 3
    "  twist_stiffness: {value: 8.0e-7}\n"                                          // 4
    "  stretch_stiffness: {value: 245}\n"                                           // 5
    "cases:\n"                                                                      // 6
    "  - name: first\n"                                                             // 7
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"     // 8
    "  - name: NAME\n"                                                              // 9
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 1, 0]}\n";    // 10

// The InputError of loading kScene with the second case named `name` (YAML text as written).
std::string CaseNameError(const TempDir& dir, const std::string& name) {
  std::string text = kScene;
  text.replace(text.find("NAME"), 4, name);
  const std::string path = dir.Write("scene.yaml", text);
  try {
    LoadExperiment(path);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "name " << name << " was accepted";
  return "";
}

TEST(HostileInput, CaseNamesThatArePathsAreRefused) {
  TempDir dir;
  const std::string prefix = dir.File("scene.yaml") + ":9: cases[1].name: ";
  for (const std::string& name :
       {std::string("../../x"), std::string("/tmp/evil"), std::string("a/b"),
        std::string("\"a\\\\b\""), std::string("\"a\\0b\""), std::string(".hidden"),
        std::string(".."), std::string("'.'")}) {
    SCOPED_TRACE(name);
    const std::string message = CaseNameError(dir, name);
    EXPECT_THAT(message, StartsWith(prefix));
    EXPECT_THAT(message, HasSubstr("file name"));
    EXPECT_EQ(message.find('\n'), std::string::npos);
  }
  // Empty: no name at all is no file name either; nor is one too long for a file system.
  EXPECT_THAT(CaseNameError(dir, "\"\""), StartsWith(prefix));
  const std::string long_name = CaseNameError(dir, std::string(300, 'n'));
  EXPECT_THAT(long_name, HasSubstr("must have at most 100 characters"));
  EXPECT_LE(long_name.size(), 300u);
  // Ordinary names still pass, dots inside included.
  std::string text = kScene;
  text.replace(text.find("NAME"), 4, "pulled.2-up_x");
  EXPECT_EQ(LoadExperiment(dir.Write("ok.yaml", text)).scene.cases[1].name, "pulled.2-up_x");
}

TEST(HostileInput, EchoedCsvFieldIsCutShort) {
  const std::string huge(1 << 20, 'x');
  const CsvTable table = CsvTable::Parse("s,x\n1," + huge + "\n", "big.csv");
  try {
    table.Column("x");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_LE(message.size(), 300u);
    EXPECT_THAT(message, StartsWith("big.csv:2: x: expected a finite number, got 'xxx"));
    EXPECT_THAT(message, EndsWith("...'"));
  }
  // A header with a megabyte-long duplicate column name.
  try {
    CsvTable::Parse(huge + "," + huge + "\n", "head.csv");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_LE(std::string(e.what()).size(), 300u);
    EXPECT_THAT(e.what(), HasSubstr("duplicate column name"));
  }
}

TEST(HostileInput, EchoedYamlValuesAndKeysAreCutShort) {
  TempDir dir;
  const std::string huge(1 << 20, '7');
  std::string text = kScene;
  text.replace(text.find("length: 0.2"), 11, "length: x" + huge);
  std::string message;
  try {
    LoadExperiment(dir.Write("value.yaml", text));
  } catch (const InputError& e) {
    message = e.what();
  }
  EXPECT_THAT(message, HasSubstr("value.yaml:1: rod.length: expected a number, got 'x777"));
  EXPECT_LE(message.size(), 300u);

  // A key (YAML limits implicit keys to 1024 characters).
  text = kScene;
  text.replace(text.find("segments: 10"), 12, "segments: 10, k" + std::string(1000, '7') + ": 1");
  message.clear();
  try {
    LoadExperiment(dir.Write("key.yaml", text));
  } catch (const InputError& e) {
    message = e.what();
  }
  EXPECT_THAT(message, HasSubstr("key.yaml:1: rod.k777"));
  EXPECT_THAT(message, HasSubstr("...: unknown key"));
  EXPECT_LE(message.size(), 300u);
  EXPECT_EQ(ClipForMessage("a\nb"), "a?b");
}

}  // namespace
}  // namespace rodfit
