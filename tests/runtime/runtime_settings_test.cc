// The runtime's options (RuntimeOptions, rodfit/runtime/runtime.h): their one declaration held
// to docs/library.md's table (a row per key with its range and default), and Check holding a
// caller's values to the same ranges, naming the key.
#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "rodfit/runtime/runtime.h"
#include "settings_docs.h"

namespace rodfit {
namespace {

const char kLibraryDoc[] = RODFIT_SOURCE_DIR "/docs/library.md";

TEST(RuntimeSettings, EveryKeyHasItsRowInTheLibraryDocs) {
  RuntimeOptions options;
  test::DocsArchive docs("runtime", kLibraryDoc);
  Serialize(&docs, &options);
  // max_iterations, time_budget, dynamic_newton_iterations, mesh_ring_vertices.
  EXPECT_EQ(docs.keys(), 4);
  EXPECT_EQ(docs.visited().size(), 13u);
  EXPECT_EQ(test::RowKeys(kLibraryDoc, "runtime"), docs.visited());
}

// The first value out of range, named with its key and range.
std::string Why(const RuntimeOptions& options) {
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  return why;
}

TEST(RuntimeSettings, CheckRefusesEachValueOutsideItsDeclaredRange) {
  RuntimeOptions ok;
  ok.tool_s = 0.1;
  std::string why;
  EXPECT_TRUE(ok.Check(&why)) << why;
  EXPECT_EQ(Why(RuntimeOptions()), "tool_s must be > 0 (is -1)");  // required: no default
  RuntimeOptions o = ok;
  o.mesh_ring_vertices = 2;
  EXPECT_EQ(Why(o), "mesh_ring_vertices must be in [3, 1024] (is 2)");
  o = ok;
  o.max_strain = 1.5;
  EXPECT_EQ(Why(o), "max_strain must be <= 1");
  o = ok;
  o.max_tool_move = 0.0;
  EXPECT_EQ(Why(o), "max_tool_move must be > 0 (is 0)");
  o = ok;
  o.time_budget = -1e-3;
  EXPECT_EQ(Why(o), "time_budget must be in [0, inf] (is -0.001)");
  o.time_budget = std::nan("");
  EXPECT_EQ(Why(o), "time_budget must be in [0, inf] (is nan)");
  o.time_budget = std::numeric_limits<double>::infinity();  // no budget (Runtime's test)
  EXPECT_TRUE(o.Check(&why)) << why;
  o = ok;
  o.gradient_tolerance = std::nan("");
  EXPECT_EQ(Why(o), "gradient_tolerance must be > 0 (is nan)");
  o = ok;
  o.max_iterations = 0;
  EXPECT_EQ(Why(o), "max_iterations must be in [1, 10000] (is 0)");
  o = ok;
  o.hold_orientation = true;
  o.tool = ToolKind::kPoke;
  EXPECT_EQ(Why(o), "hold_orientation is for a quasi-static grasp only");
}

}  // namespace
}  // namespace rodfit
