// The one exception type of the io layer: a user's mistake in an input file (or an output path),
// carrying where it is. what() is a single line `FILE:LINE: KEY: message`,
// with `:LINE` left out when the line is unknown and `KEY: ` when no key applies, so the CLI can
// print it as is.
#pragma once

#include <stdexcept>
#include <string>

namespace rodfit {

/// An input value as an error message may echo it: at most `max_chars` characters, longer ones
/// cut with "...", line breaks and other control characters as '?', so that a 1 MiB field or a
/// binary file never makes a message longer than a line (at most ~300 characters).
inline std::string ClipForMessage(const std::string& value, size_t max_chars = 80) {
  std::string out;
  const size_t n = value.size() > max_chars ? max_chars - 3 : value.size();
  out.reserve(n + 3);
  for (size_t i = 0; i < n; ++i) {
    const unsigned char c = static_cast<unsigned char>(value[i]);
    out += (c < 0x20 || c == 0x7f) ? '?' : value[i];
  }
  if (value.size() > max_chars) out += "...";
  return out;
}

/// `text` with its line breaks turned into spaces: every error is one line.
inline std::string OneLine(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

/// "FILE:LINE: case NAME: " (LINE left out when unknown, 0): where a case the solver cannot
/// settle is written, named like an input error's place, so that a scene of many cases points at
/// the one to change.
inline std::string CasePlace(const std::string& file, int line, const std::string& name) {
  return file + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": case " + name + ": ";
}

struct InputError : std::runtime_error {
  /// line is 1-based; line <= 0 means unknown. key is a dotted path such as `rod.length` or
  /// `cases[1].clamp.normal` (YAML) or a column name (CSV); empty when none applies.
  InputError(const std::string& file, int line, const std::string& key, const std::string& message)
      : std::runtime_error(Format(file, line, key, message)),
        file(file),
        line(line),
        key(key),
        message(message) {}

  std::string file;
  int line;
  std::string key;
  std::string message;

 private:
  static std::string Format(const std::string& file, int line, const std::string& key,
                            const std::string& message) {
    std::string out = file;
    if (line > 0) out += ":" + std::to_string(line);
    out += ": ";
    if (!key.empty()) out += key + ": ";
    out += message;
    // One line, whatever a library message or a file name contains.
    for (char& c : out) {
      if (c == '\n' || c == '\r') c = ' ';
    }
    return out;
  }
};

}  // namespace rodfit
