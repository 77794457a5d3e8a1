// The settings' one declaration (rodfit/io/settings.h) against their documentation: every key
// that Serialize declares for `solver:`, `fit:` and `dynamics:` has its row in docs/formats.md's
// table, and that row states the key's range and its default as the structs declare them (or
// that it is required), so that neither can change without the other.
#include "rodfit/io/settings.h"

#include <cstdlib>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "io/temp_dir.h"
#include "rodfit/solve/integrator.h"

namespace rodfit {
namespace {

// The documentation row of `key` in docs/formats.md, or "" when there is none.
std::string Row(const std::string& key) {
  static const std::string docs = test::ReadText(RODFIT_SOURCE_DIR "/docs/formats.md");
  const std::string start = "| `" + key + "` |";
  const size_t at = docs.find(start);
  if (at == std::string::npos) return "";
  return docs.substr(at, docs.find('\n', at) - at);
}

// The numbers a text states right after `marker` (e.g. "[", "default "), in order.
std::vector<double> NumbersAfter(const std::string& text, const std::string& marker, int count) {
  std::vector<double> out;
  size_t at = text.find(marker);
  if (at == std::string::npos) return out;
  const char* p = text.c_str() + at + marker.size();
  for (int k = 0; k < count; ++k) {
    char* end = nullptr;
    const double v = std::strtod(p, &end);
    if (end == p) break;
    out.push_back(v);
    p = end;
    while (*p == ',' || *p == ' ') ++p;
  }
  return out;
}

// Checks each declared key's row: its range, its default or that it is required.
class DocsArchive final : public SettingsArchive {
 public:
  explicit DocsArchive(std::string block) : block_(std::move(block)) {}
  int keys() const { return keys_; }

  bool reading() const override { return false; }
  void Integer(const char* key, int* value, int lo, int hi) override {
    Range(key, lo, hi);
    Default(key, *value);
  }
  void Count(const char* key, int* value, int lo, int hi) override {
    Integer(key, value, lo, hi);
  }
  void Number(const char* key, double* value, double lo, double hi) override {
    Range(key, lo, hi);
    Default(key, *value);
  }
  void Positive(const char* key, double* value) override {
    EXPECT_NE(RowOf(key).find("> 0"), std::string::npos) << RowOf(key);
    Default(key, *value);
  }
  void Bool(const char* key, bool* value) override {
    const std::string row = RowOf(key);
    EXPECT_NE(row.find(std::string("default ") + (*value ? "true" : "false")), std::string::npos)
        << row;
  }
  void Choice(const char* key, int* index, const std::vector<std::string>& words,
              const std::string&) override {
    const std::string row = RowOf(key);
    for (const std::string& word : words)
      EXPECT_NE(row.find("`" + word + "`"), std::string::npos) << word << " in " << row;
    EXPECT_NE(row.find("`" + words[*index] + "` (default"), std::string::npos) << row;
  }
  void Require(const char* key) override {
    required_.push_back(key);
    EXPECT_NE(RowOf(key).find("| yes |"), std::string::npos) << RowOf(key);
  }
  bool Has(const char*) const override { return false; }
  void Check(bool, const char*, const std::string&) override {}

 private:
  std::string RowOf(const char* key) {
    const std::string row = Row(block_ + "." + key);
    EXPECT_FALSE(row.empty()) << block_ << "." << key << " has no row in docs/formats.md";
    return row;
  }
  void Range(const char* key, double lo, double hi) {
    ++keys_;
    const std::string row = RowOf(key);
    const std::vector<double> range = NumbersAfter(row, "in [", 2);
    ASSERT_GE(range.size(), 1u) << row;
    EXPECT_DOUBLE_EQ(range[0], lo) << row;
    // An upper bound that is another setting is named by its key (min_time_step's `time_step`).
    if (range.size() == 2) EXPECT_DOUBLE_EQ(range[1], hi) << row;
    else EXPECT_NE(row.find(", `"), std::string::npos) << row;
  }
  void Default(const char* key, double value) {
    for (const std::string& r : required_)
      if (r == key) return;  // a required key has no default
    const std::string row = RowOf(key);
    const std::vector<double> d = NumbersAfter(row, "default ", 1);
    ASSERT_EQ(d.size(), 1u) << row;
    EXPECT_DOUBLE_EQ(d[0], value) << row;
  }

  std::string block_;
  std::vector<std::string> required_;
  int keys_ = 0;
};

TEST(SettingsDocs, EveryKeyHasItsRangeAndDefaultInTheDocs) {
  StaticsOptions statics;
  DocsArchive solver("solver");
  Serialize(&solver, &statics);
  FitOptions fit;
  DocsArchive fitting("fit");
  Serialize(&fitting, &fit);
  DynamicsSpec dynamics;
  DocsArchive moving("dynamics");
  Serialize(&moving, &dynamics, IntegratorNames());
  // The numeric keys were all visited (a Serialize that declares none would pass vacuously).
  EXPECT_EQ(solver.keys(), 3);
  EXPECT_EQ(fitting.keys(), 1);
  EXPECT_EQ(moving.keys(), 6);
}

}  // namespace
}  // namespace rodfit
