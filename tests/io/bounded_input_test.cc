// Input files bounded before they are parsed (io/csv.h): only regular files of at most
// kMaxInputFileBytes reach a parser (a directory, /dev/zero, a FIFO or a huge file is a one-line
// error naming it, and nothing is read whole), and a CSV table holds at most kMaxCsvRows rows
// and kMaxCsvFieldBytes per field.
#include <sys/stat.h>

#include <filesystem>
#include <functional>
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

namespace fs = std::filesystem;
using test::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return "";
}

TEST(BoundedInput, OnlyRegularFilesAreRead) {
  TempDir dir;
  const std::string folder = dir.File("folder.csv");
  fs::create_directory(folder);
  const std::string fifo = dir.File("fifo.csv");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // A FIFO without a writer would block a reader forever; /dev/zero never ends.
  for (const std::string& path : {fifo, std::string("/dev/zero")}) {
    SCOPED_TRACE(path);
    EXPECT_EQ(ErrorOf([&] { CsvTable::Read(path); }),
              path + ": is not a regular file (a device, FIFO or socket); a CSV file must be a "
                     "file");
    EXPECT_THAT(ErrorOf([&] { LoadExperiment(path); }),
                StartsWith(path + ": is not a regular file"));
  }
  EXPECT_EQ(ErrorOf([&] { CsvTable::Read(folder); }), folder + ": is a directory, not a CSV file");
  EXPECT_EQ(ErrorOf([&] { LoadExperiment(folder); }),
            folder + ": is a directory, not a YAML file");
}

TEST(BoundedInput, FilesLargerThanTheLimitAreRefusedUnread) {
  TempDir dir;
  // Sparse: the size is there, the disk space not; the refusal comes from the size alone.
  for (const std::string name : {"big.csv", "big.yaml"}) {
    const std::string path = dir.Write(name, "");
    fs::resize_file(path, kMaxInputFileBytes + 1);
    const std::string error = ErrorOf([&] {
      if (name == "big.csv") {
        CsvTable::Read(path);
      } else {
        LoadExperiment(path);
      }
    });
    EXPECT_THAT(error, StartsWith(path + ": is 268435457 bytes, too large for a "));
    // A YAML file has a limit of its own (yaml-cpp needs many times a file's size in memory).
    EXPECT_THAT(error, HasSubstr(name == "big.csv" ? "(at most 268435456)" : "(at most 4194304)"));
  }
  {
    const std::string path = dir.Write("four.yaml", "");
    fs::resize_file(path, kMaxYamlBytes + 1);
    EXPECT_THAT(ErrorOf([&] { LoadExperiment(path); }),
                HasSubstr("is 4194305 bytes, too large for a YAML file (at most 4194304)"));
  }
  // At the limit a file is read (and here fails on its content, not its size).
  const std::string small = dir.Write("small.csv", "");
  fs::resize_file(small, 1000);
  EXPECT_THAT(ErrorOf([&] { ReadInputFile(small, "a test file", 999); }),
              HasSubstr("too large"));
  EXPECT_EQ(ReadInputFile(small, "a test file", 1000), std::string(1000, '\0'));
}

TEST(BoundedInput, CsvRowsAndFieldsAreBounded) {
  std::string rows = "s\n";
  rows.reserve(2 * (kMaxCsvRows + 2));
  for (int r = 0; r < kMaxCsvRows; ++r) rows += "0\n";
  EXPECT_EQ(CsvTable::Parse(rows, "m.csv").num_rows(), kMaxCsvRows);
  rows += "0\n";
  EXPECT_EQ(ErrorOf([&] { CsvTable::Parse(rows, "m.csv"); }),
            "m.csv:" + std::to_string(kMaxCsvRows + 2) +
                ": more than 1000000 data rows (the limit)");

  const std::string field(kMaxCsvFieldBytes, '9');
  EXPECT_EQ(CsvTable::Parse("s,x\n0," + field + "\n", "m.csv").num_rows(), 1);
  const std::string error =
      ErrorOf([&] { CsvTable::Parse("s,x\n0," + field + "9\n", "m.csv"); });
  EXPECT_EQ(error, "m.csv:2: field 2 is 4194305 bytes long (at most 4194304)");
}

}  // namespace
}  // namespace rodfit
