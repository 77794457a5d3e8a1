// The documentation of settings held to their declaration (rodfit/model/settings_archive.h):
// DocsArchive, run through a configuration's Serialize, checks that each key has its row in a
// documentation table (`| `block.key` | ...`) stating its range and its default as the struct
// declares them (or that it is required), and in a table with an option column its
// command-line option or `—`. Used by tests/io/settings_docs_test.cc and
// tests/runtime/runtime_settings_docs_test.cc.
#pragma once

#include <cstdlib>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "io/temp_dir.h"
#include "rodfit/model/settings_archive.h"

namespace rodfit::test {


inline const char kFormatsDoc[] = RODFIT_SOURCE_DIR "/docs/formats.md";
inline const char kCliDoc[] = RODFIT_SOURCE_DIR "/docs/cli.md";

// The documentation row of `key` in `doc`, or "" when there is none.
inline std::string Row(const std::string& doc, const std::string& key) {
  const std::string docs = ReadText(doc);
  const std::string start = "| `" + key + "` |";
  const size_t at = docs.find(start);
  if (at == std::string::npos) return "";
  return docs.substr(at, docs.find('\n', at) - at);
}

// The keys of the rows of `doc` whose key starts with `block.` (a table's first column).
inline std::set<std::string> RowKeys(const std::string& doc, const std::string& block) {
  const std::string docs = ReadText(doc);
  const std::string start = "\n| `" + block + ".";
  std::set<std::string> keys;
  for (size_t at = docs.find(start); at != std::string::npos; at = docs.find(start, at + 1)) {
    const size_t from = at + start.size();
    keys.insert(docs.substr(from, docs.find('`', from) - from));
  }
  return keys;
}

// The numbers a text states right after `marker` (e.g. "[", "default "), in order.
inline std::vector<double> NumbersAfter(const std::string& text, const std::string& marker, int count) {
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

// Checks each declared key's row: its range, its default or that it is required; in a table
// with an option column (`options`), the key's command-line option or `—`.
class DocsArchive final : public SettingsArchive {
 public:
  explicit DocsArchive(std::string block, std::string doc = kFormatsDoc, bool options = false)
      : block_(std::move(block)), doc_(std::move(doc)), options_(options) {}
  int keys() const { return keys_; }
  const std::set<std::string>& visited() const { return visited_; }

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
  void IntegerList(const char* key, std::vector<int>* value) override {
    std::string list;
    for (int v : *value) list += (list.empty() ? "" : ",") + std::to_string(v);
    EXPECT_NE(RowOf(key).find("default " + list), std::string::npos) << RowOf(key);
  }
  bool Has(const char*) const override { return false; }
  void Check(bool, const char*, const std::string&) override {}
  void Describe(const char* key, const char* option, const std::string& help) override {
    EXPECT_FALSE(help.empty()) << key;
    described_key_ = key;
    described_option_ = option;
  }

 private:
  std::string RowOf(const char* key) {
    const std::string row = Row(doc_, block_ + "." + key);
    EXPECT_FALSE(row.empty()) << block_ << "." << key << " has no row in " << doc_;
    if (visited_.insert(key).second && options_) {
      // The option the visitor describes right before the key, or none.
      const std::string option = described_key_ == key ? "`" + described_option_ + "`" : "—";
      EXPECT_NE(row.find("| " + option + " |"), std::string::npos) << option << " in " << row;
    }
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

  std::string block_, doc_;
  bool options_;
  std::vector<std::string> required_;
  std::set<std::string> visited_;
  std::string described_key_, described_option_;
  int keys_ = 0;
};

}  // namespace rodfit::test
