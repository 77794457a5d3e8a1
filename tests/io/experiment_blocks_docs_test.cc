// The experiment YAML's blocks (rodfit/io/experiment_blocks.h) against docs/formats.md: every key
// a block declares is documented — its own row (`cases[i].clamp.normal`), or named in its
// block's row (`{s, force}`) — and every row of the "Scene / experiment YAML" table names a key
// the reader takes, so that a key added, renamed or dropped on one side fails here. The reader's
// use of the tables (unknown keys, their messages) is held by experiment_test.cc and the fuzz
// corpus (test_cli).
#include "rodfit/io/experiment_blocks.h"

#include <algorithm>
#include <cctype>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "settings_docs.h"

namespace rodfit {
namespace {

namespace blocks = experiment_blocks;

// The docs' list items `[i]`, `[k]` dropped, so that `cases[i].pins` and `pins[k]` read as the
// dotted paths they are.
std::string Normalized(std::string text) {
  for (const std::string item : {"[i]", "[k]"})
    for (size_t at = text.find(item); at != std::string::npos; at = text.find(item, at))
      text.erase(at, item.size());
  return text;
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// `word` in `text` with no letter, digit or underscore on either side.
bool HasWord(const std::string& text, const std::string& word) {
  auto identifier = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
  for (size_t at = text.find(word); at != std::string::npos; at = text.find(word, at + 1)) {
    const bool start = at == 0 || !identifier(text[at - 1]);
    const size_t end = at + word.size();
    if (start && (end == text.size() || !identifier(text[end]))) return true;
  }
  return false;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// Whether docs/formats.md (normalized) documents `key` of the block at `path` (normalized).
bool Documented(const std::string& doc, const std::string& path, const std::string& key) {
  const std::string full = path.empty() ? key : path + "." + key;
  // Its own row or mention, or the rows of a block below it (`rod.length` for `rod`).
  if (Contains(doc, "`" + full + "`") || Contains(doc, "`" + full + ".")) return true;
  // Named from its list's item (`pins.position_prior` in a row of several paths).
  const size_t dot = path.rfind('.');
  if (dot != std::string::npos && Contains(doc, "`" + path.substr(dot + 1) + "." + key + "`"))
    return true;
  for (const std::string& line : Lines(doc)) {
    // A row of several keys of the block (`parameters.NAME.min`, `.max`).
    if (!path.empty() && Contains(line, "| `" + path + ".") && Contains(line, "`.") &&
        Contains(line, "`." + key + "`"))
      return true;
    // The block's own row naming it (`{s, force}`, `radius` [m] ...).
    if (!path.empty() && line.rfind("| `" + path + "` |", 0) == 0) {
      const std::string text = line.substr(path.size() + 6);
      if (HasWord(text, key)) return true;
    }
  }
  return false;
}

TEST(ExperimentBlocksDocs, EveryDeclaredKeyIsDocumented) {
  const std::string doc = Normalized(test::ReadText(test::kFormatsDoc));
  int keys = 0;
  for (const blocks::Block* block : blocks::AllBlocks())
    for (const std::string& path : block->paths)
      for (const std::string& key : block->keys) {
        EXPECT_TRUE(Documented(doc, Normalized(path), key))
            << "`" << (path.empty() ? "" : path + ".") << key << "` has no row in docs/formats.md";
        ++keys;
      }
  // Every block was visited (an empty table would pass vacuously): 20 blocks, 87 keys with the
  // held frame's under both its paths.
  EXPECT_EQ(blocks::AllBlocks().size(), 20u);
  EXPECT_EQ(keys, 87);
}

// The rows of the "Scene / experiment YAML" table name keys the reader takes: each row's first
// path starts with a key of the document, and a row under a declared block names one of its keys.
TEST(ExperimentBlocksDocs, EveryRowNamesADeclaredKey) {
  const std::string text = test::ReadText(test::kFormatsDoc);
  const size_t from = text.find("## Scene / experiment YAML");
  ASSERT_NE(from, std::string::npos);
  const size_t to = text.find("\n## ", from + 1);
  const std::string section = Normalized(text.substr(from, to - from));
  std::set<std::string> paths;
  for (const blocks::Block* block : blocks::AllBlocks())
    for (const std::string& path : block->paths) paths.insert(Normalized(path));
  auto keys_of = [](const std::string& path) {
    for (const blocks::Block* block : blocks::AllBlocks())
      for (const std::string& p : block->paths)
        if (Normalized(p) == path) return block->keys;
    return std::vector<std::string>();
  };
  const std::vector<std::string>& top = blocks::kDocument.keys;
  int rows = 0;
  for (const std::string& line : Lines(section)) {
    if (line.rfind("| `", 0) != 0) continue;
    const std::string cell = line.substr(3, line.find(" |", 3) - 3);
    const std::string first = cell.substr(0, cell.find('`'));
    ++rows;
    EXPECT_NE(std::find(top.begin(), top.end(), first.substr(0, first.find('.'))), top.end())
        << line;
    const size_t dot = first.rfind('.');
    if (dot == std::string::npos) continue;
    // The row's path may continue into a block's key (`cases.clamp.position`).
    const std::string prefix = first.substr(0, dot), key = first.substr(dot + 1);
    if (paths.count(prefix)) {
      const std::vector<std::string> keys = keys_of(prefix);
      EXPECT_NE(std::find(keys.begin(), keys.end(), key), keys.end()) << line;
    }
  }
  EXPECT_GT(rows, 60);
}

}  // namespace
}  // namespace rodfit
