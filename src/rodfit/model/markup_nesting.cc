// The nesting bound of markup texts (markup_nesting.h).
#include "rodfit/model/markup_nesting.h"

#include <algorithm>
#include <string>
#include <vector>

namespace rodfit {

// The deepest nesting of a YAML, JSON or XML text, as a bound (not a parse): brackets and braces
// outside quotes and comments; for XML, open elements; for YAML, indentation levels and "- "
// entries too. It may overestimate odd but valid files, never underestimate the nesting a
// parser recurses into.
int MarkupNestingDepth(const std::string& text) {
  const size_t begin = std::min(text.find_first_not_of(" \t\r\n"), text.size());
  if (begin == text.size()) return 0;
  const char first = text[begin];
  int deepest = 0;
  if (first == '<') {
    int depth = 0;
    for (size_t i = text.find('<'); i != std::string::npos; i = text.find('<', i + 1)) {
      const size_t close = text.find('>', i);
      if (close == std::string::npos) break;
      const char next = i + 1 < text.size() ? text[i + 1] : '\0';
      if (next == '/') {
        depth = std::max(depth - 1, 0);
      } else if (next != '?' && next != '!' && text[close - 1] != '/') {
        deepest = std::max(deepest, ++depth);
      }
      i = close;
    }
    return deepest;
  }
  int flow = 0;                 // open [ and { (JSON, YAML flow collections)
  std::vector<size_t> blocks;   // YAML: columns of the open block levels
  size_t pos = 0;
  while (pos < text.size()) {
    const size_t end = std::min(text.find('\n', pos), text.size());
    const std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    size_t i = line.find_first_not_of(' ');
    if (i == std::string::npos || line[i] == '#' || line[i] == '%') continue;
    if (first != '{' && flow == 0) {
      while (!blocks.empty() && blocks.back() > i) blocks.pop_back();
      if (blocks.empty() || blocks.back() < i) blocks.push_back(i);
      // "- - x": each dash opens a sequence level of its own.
      while (i + 1 < line.size() && line[i] == '-' && line[i + 1] == ' ') {
        i = line.find_first_not_of(' ', i + 1);
        if (i == std::string::npos) break;
        blocks.push_back(i);
      }
    }
    char quote = '\0';
    for (size_t k = 0; k < line.size(); ++k) {
      const char c = line[k];
      if (quote != '\0') {
        if (c == quote) quote = '\0';
      } else if (c == '"' || (c == '\'' && first != '{')) {
        quote = c;
      } else if (c == '#' && first != '{' && (k == 0 || line[k - 1] == ' ' || line[k - 1] == '\t')) {
        break;  // a YAML comment: its brackets open nothing
      } else if (c == '[' || c == '{') {
        ++flow;
      } else if (c == ']' || c == '}') {
        flow = std::max(flow - 1, 0);
      }
      deepest = std::max(deepest, static_cast<int>(blocks.size()) + flow);
    }
    deepest = std::max(deepest, static_cast<int>(blocks.size()) + flow);
  }
  return deepest;
}

}  // namespace rodfit
