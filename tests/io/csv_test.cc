// Tests of the CSV reader, number formatting, atomic writes and mkdir -p (io/csv.h) and of the
// shapes.csv writer (io/shapes_csv.h).
#include "rodfit/io/csv.h"

#include <algorithm>
#include <filesystem>
#include <functional>
#include <limits>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/errors.h"
#include "rodfit/io/shapes_csv.h"
#include "temp_dir.h"

namespace rodfit {
namespace {

using test::ReadText;
using test::TempDir;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return "";
}

std::vector<std::string> Listing(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

TEST(CsvTable, ColumnsByNameExtraColumnsIgnored) {
  const CsvTable t = CsvTable::Parse(
      "\xEF\xBB\xBF"
      "id, z ,y,x,s\r\n"
      "# a comment line\n"
      "\n"
      "a,3,2,1,0.5\r\n"
      "\"b, quoted\",6,5,+4,1e-3\n",
      "m.csv");
  EXPECT_EQ(t.num_rows(), 2);
  EXPECT_EQ(t.line(0), 4);
  EXPECT_EQ(t.line(1), 5);
  EXPECT_THAT(t.Column("x"), ElementsAre(1.0, 4.0));
  EXPECT_THAT(t.Column("s"), ElementsAre(0.5, 1e-3));
  EXPECT_THAT(t.Column("z"), ElementsAre(3.0, 6.0));
  EXPECT_THAT(t.TextColumn("id"), ElementsAre("a", "b, quoted"));
  EXPECT_TRUE(t.HasColumn("y"));
  EXPECT_FALSE(t.HasColumn("u"));
}

TEST(CsvTable, MissingColumnNamesFileAndColumn) {
  const CsvTable t = CsvTable::Parse("s,x,y\n0,1,2\n", "markers.csv");
  EXPECT_THAT(ErrorOf([&] { t.Column("z"); }), HasSubstr("markers.csv: z: missing column"));
  EXPECT_THAT(ErrorOf([&] { t.TextColumn("case"); }), HasSubstr("markers.csv: case: missing"));
}

// As motion-capture software and spreadsheets export them: capitalised headers are read;
// a header separated by ';' or tabs is said as such rather than as missing columns.
TEST(CsvTable, ColumnNamesInAnyCaseAndOtherSeparatorsSaid) {
  const CsvTable t = CsvTable::Parse("Frame,Marker,X,Y,Z\n0,1,2,3,4\n", "mocap.csv");
  EXPECT_THAT(t.Column("frame"), ElementsAre(0.0));
  EXPECT_THAT(t.Column("x"), ElementsAre(2.0));
  EXPECT_TRUE(t.HasColumn("marker"));
  EXPECT_THAT(ErrorOf([] { CsvTable::Parse("x,X\n1,2\n", "m.csv"); }),
              HasSubstr("m.csv:1: X: duplicate column name"));
  EXPECT_THAT(ErrorOf([] { CsvTable::Parse("t;s;x;y;z\n0;0;0,1;0;0\n", "excel.csv"); }),
              HasSubstr("excel.csv:1: the header is separated by ';': rodfit reads comma-separated"));
  EXPECT_THAT(ErrorOf([] { CsvTable::Parse("t\ts\tx\n0\t0\t1\n", "tab.csv"); }),
              HasSubstr("tab.csv:1: the header is separated by tabs"));
  const CsvTable u = CsvTable::Parse("s,x,y\n0,1,2\n", "markers.csv");
  EXPECT_THAT(ErrorOf([&] { u.Column("z"); }), HasSubstr("missing column (the header has s,x,y)"));
}

TEST(CsvTable, BadNumbersNameFileLineAndColumn) {
  const CsvTable t =
      CsvTable::Parse("s,x\n0,1\n\n0.1,abc\n0.2,nan\n0.3,-inf\n0.4,1.5x\n0.5,\n", "m.csv");
  EXPECT_THAT(t.Column("s"), ElementsAre(0, 0.1, 0.2, 0.3, 0.4, 0.5));
  EXPECT_THAT(ErrorOf([&] { t.Column("x"); }), HasSubstr("m.csv:4: x: expected a finite number"));
  const CsvTable nan = CsvTable::Parse("x\n1\nnan\n", "n.csv");
  EXPECT_THAT(ErrorOf([&] { nan.Column("x"); }), HasSubstr("n.csv:3: x: "));
  const CsvTable inf = CsvTable::Parse("x\n-inf\n", "i.csv");
  EXPECT_THAT(ErrorOf([&] { inf.Column("x"); }), HasSubstr("i.csv:2: x: "));
  const CsvTable trailing = CsvTable::Parse("x\n1.5x\n", "t.csv");
  EXPECT_THAT(ErrorOf([&] { trailing.Column("x"); }), HasSubstr("t.csv:2: x: "));
  const CsvTable empty = CsvTable::Parse("x,y\n1,\n", "e.csv");
  EXPECT_THAT(ErrorOf([&] { empty.Column("y"); }), HasSubstr("e.csv:2: y: "));
}

TEST(CsvTable, MalformedFiles) {
  EXPECT_THAT(ErrorOf([] { CsvTable::Parse("s,x\n0,1\n0\n", "m.csv"); }),
              HasSubstr("m.csv:3: expected 2 fields"));
  EXPECT_THAT(ErrorOf([] { CsvTable::Parse("s,x,s\n", "m.csv"); }),
              HasSubstr("m.csv:1: s: duplicate column"));
  EXPECT_THAT(ErrorOf([] { CsvTable::Parse("# only a comment\n", "m.csv"); }),
              HasSubstr("m.csv: no header row"));
  EXPECT_THAT(ErrorOf([] { CsvTable::Parse("a\n\"open\n", "m.csv"); }),
              HasSubstr("m.csv:2: unterminated"));
  EXPECT_THAT(ErrorOf([] { CsvTable::Read("/nonexistent/m.csv"); }),
              HasSubstr("/nonexistent/m.csv: cannot open"));
}

TEST(CsvTable, ReadsAFile) {
  TempDir dir;
  const CsvTable t = CsvTable::Read(dir.Write("p.csv", "x,y,z\n1,2,3\n"));
  EXPECT_EQ(t.name(), dir.File("p.csv"));
  EXPECT_THAT(t.Column("y"), ElementsAre(2.0));
}

TEST(FormatDouble, RoundTripsExactly) {
  for (double v : {0.1, 1.0 / 3.0, -9.81, 5.6e-5, 1e-300, 0.0, std::numeric_limits<double>::max(),
                   std::numeric_limits<double>::denorm_min()}) {
    double back = 0.0;
    ASSERT_TRUE(ParseDouble(FormatDouble(v), &back)) << FormatDouble(v);
    EXPECT_EQ(back, v);
  }
  EXPECT_EQ(FormatDouble(0.1), "0.10000000000000001");
  EXPECT_EQ(FormatDouble(2.0), "2");
}

TEST(WriteFileAtomically, WritesAndReplaces) {
  TempDir dir;
  const std::string path = dir.File("out.txt");
  WriteFileAtomically(path, "first\n");
  EXPECT_EQ(ReadText(path), "first\n");
  WriteFileAtomically(path, "second\n");
  EXPECT_EQ(ReadText(path), "second\n");
  EXPECT_THAT(Listing(dir.path()), ElementsAre("out.txt"));  // no temporary left behind
}

TEST(WriteFileAtomically, MissingDirectoryIsAnErrorNamingThePath) {
  TempDir dir;
  const std::string path = dir.File("no/such/dir/out.txt");
  EXPECT_THAT(ErrorOf([&] { WriteFileAtomically(path, "x"); }), HasSubstr(path + ": "));
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_TRUE(Listing(dir.path()).empty());
  EXPECT_THAT(ErrorOf([] { WriteFileAtomically("/proc/forbidden/out.txt", "x"); }),
              HasSubstr("/proc/forbidden/out.txt: "));
}

TEST(WriteFileAtomically, FailedRenameLeavesNoPartialFile) {
  TempDir dir;
  // The target is a directory: the temporary file is written, the rename fails.
  std::filesystem::create_directory(dir.File("target"));
  EXPECT_THAT(ErrorOf([&] { WriteFileAtomically(dir.File("target"), "data"); }),
              HasSubstr(dir.File("target") + ": cannot replace"));
  EXPECT_THAT(Listing(dir.path()), ElementsAre("target"));
  EXPECT_TRUE(Listing(dir.File("target")).empty());
}

TEST(CreateDirectories, MkdirMinusP) {
  TempDir dir;
  CreateDirectories(dir.File("a/b/c/"));
  EXPECT_TRUE(std::filesystem::is_directory(dir.File("a/b/c")));
  CreateDirectories(dir.File("a/b/c"));  // existing: fine
  dir.Write("file", "x");
  EXPECT_THAT(ErrorOf([&] { CreateDirectories(dir.File("file/sub")); }),
              HasSubstr(dir.File("file/sub") + ": cannot create directory"));
  EXPECT_THAT(ErrorOf([&] { CreateDirectories(dir.File("file")); }),
              HasSubstr(dir.File("file") + ": "));
}

TEST(ShapesCsv, FormatsEveryVertexAtFullPrecisionAndReadsBack) {
  CaseShape a{"sag", {0.0, 0.1, 0.2}, Eigen::Matrix3Xd(3, 3)};
  a.x << 0.0, 0.1, 1.0 / 3.0,  //
      0.0, 0.0, 0.0,           //
      0.0, -0.01, -5.6e-5;
  CaseShape b{"tip", {0.0, 0.2}, Eigen::Matrix3Xd::Zero(3, 2)};
  const std::string text = FormatShapesCsv({a, b});
  EXPECT_EQ(text.substr(0, text.find('\n')), "case,vertex,s,x,y,z");
  EXPECT_THAT(
      text,
      HasSubstr("\nsag,2,0.20000000000000001,0.33333333333333331,0,-5.5999999999999999e-05\n"));
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1 + 3 + 2);

  TempDir dir;
  WriteShapesCsv(dir.File("shapes.csv"), {a, b});
  const std::vector<CaseShape> back = ReadShapesCsv(dir.File("shapes.csv"));
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].name, "sag");
  EXPECT_EQ(back[0].s, a.s);
  EXPECT_EQ(back[0].x, a.x);  // bit-exact
  EXPECT_EQ(back[1].name, "tip");
  EXPECT_EQ(back[1].x.cols(), 2);
}

TEST(ShapesCsv, ReadRejectsBrokenVertexSequences) {
  TempDir dir;
  const std::string path =
      dir.Write("shapes.csv", "case,vertex,s,x,y,z\na,0,0,0,0,0\na,2,0,0,0,0\n");
  EXPECT_THAT(ErrorOf([&] { ReadShapesCsv(path); }), HasSubstr(path + ":3: vertex: "));
  EXPECT_THROW(FormatShapesCsv({CaseShape{"a", {0.0}, Eigen::Matrix3Xd::Zero(3, 2)}}),
               std::invalid_argument);
}

}  // namespace
}  // namespace rodfit
