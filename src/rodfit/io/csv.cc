// CSV reading, atomic file writing and number formatting (see csv.h).
#include "rodfit/io/csv.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <cctype>
#include <fstream>
#include <sstream>
#include <system_error>

#include "rodfit/io/errors.h"

namespace rodfit {
namespace {

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string Trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  const auto last = s.find_last_not_of(" \t");
  return s.substr(first, last - first + 1);
}

// Splits one line into fields; returns false with *why set on an unterminated or misplaced quote.
bool SplitFields(const std::string& line, std::vector<std::string>* fields, std::string* why) {
  fields->clear();
  size_t i = 0;
  while (true) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    std::string field;
    if (i < line.size() && line[i] == '"') {
      ++i;
      while (true) {
        if (i >= line.size()) {
          *why = "unterminated quoted field";
          return false;
        }
        if (line[i] == '"') {
          if (i + 1 < line.size() && line[i + 1] == '"') {
            field += '"';
            i += 2;
            continue;
          }
          ++i;
          break;
        }
        field += line[i++];
      }
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
      if (i < line.size() && line[i] != ',') {
        *why = "unexpected text after a quoted field";
        return false;
      }
    } else {
      const size_t end = std::min(line.find(',', i), line.size());
      field = Trim(line.substr(i, end - i));
      i = end;
    }
    fields->push_back(field);
    if (i >= line.size()) return true;
    ++i;  // the comma; a trailing comma leaves an empty last field
  }
}

std::string ErrnoMessage(int err) { return std::generic_category().message(err); }

// Refuses what is not a regular file of at most max_bytes, from its stat.
void CheckStat(const std::string& path, const struct stat& st, const std::string& what,
               std::uintmax_t max_bytes) {
  if (S_ISDIR(st.st_mode)) throw InputError(path, 0, "", "is a directory, not " + what);
  if (!S_ISREG(st.st_mode)) {
    throw InputError(path, 0, "", "is not a regular file (a device, FIFO or socket); " + what +
                                      " must be a file");
  }
  if (static_cast<std::uintmax_t>(st.st_size) > max_bytes) {
    throw InputError(path, 0, "", "is " + std::to_string(st.st_size) + " bytes, too large for " +
                                      what + " (at most " + std::to_string(max_bytes) + ")");
  }
}

}  // namespace

void CheckInputFile(const std::string& path, const std::string& what, std::uintmax_t max_bytes) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    throw InputError(path, 0, "", "cannot open file: " + ErrnoMessage(errno));
  }
  CheckStat(path, st, what, max_bytes);
}

std::string ReadInputFile(const std::string& path, const std::string& what,
                          std::uintmax_t max_bytes) {
  CheckInputFile(path, what, max_bytes);
  // O_NONBLOCK: should the path have become a FIFO since the check, open does not wait for a
  // writer; fstat then refuses it.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw InputError(path, 0, "", "cannot open file: " + ErrnoMessage(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st;
  if (::fstat(fd, &st) != 0) throw InputError(path, 0, "", "cannot read file: " + ErrnoMessage(errno));
  CheckStat(path, st, what, max_bytes);
  std::string text(static_cast<size_t>(st.st_size), '\0');
  size_t have = 0;
  while (true) {
    if (have == text.size()) {
      if (text.size() > max_bytes) {
        throw InputError(path, 0, "", "grew while read, too large for " + what + " (at most " +
                                          std::to_string(max_bytes) + " bytes)");
      }
      // One byte more than expected: end of file, or a file that grew.
      text.resize(std::min<std::uintmax_t>(max_bytes + 1, text.size() + 65536));
    }
    const ssize_t n = ::read(fd, &text[have], text.size() - have);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw InputError(path, 0, "", "cannot read file: " + ErrnoMessage(errno));
    }
    if (n == 0) break;
    have += static_cast<size_t>(n);
  }
  text.resize(have);
  // A compressed file (recording.csv.gz) would otherwise be parsed as text and refused for its
  // field counts: said for what it is.
  if (text.size() >= 2 && static_cast<unsigned char>(text[0]) == 0x1f &&
      static_cast<unsigned char>(text[1]) == 0x8b)
    throw InputError(path, 0, "", "is gzip-compressed; decompress it first (gunzip) to read it as " + what);
  return text;
}

CsvTable CsvTable::Read(const std::string& path) {
  return Parse(ReadInputFile(path, "a CSV file"), path);
}

CsvTable CsvTable::Parse(const std::string& text, const std::string& name) {
  CsvTable table;
  table.name_ = name;
  size_t pos = 0;
  if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) pos = 3;  // byte-order mark from spreadsheets
  int line_number = 0;
  bool have_header = false;
  std::vector<std::string> fields;
  std::string why;
  while (pos < text.size()) {
    const size_t end = std::min(text.find('\n', pos), text.size());
    std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    if (!SplitFields(line, &fields, &why)) throw InputError(name, line_number, "", why);
    for (size_t c = 0; c < fields.size(); ++c) {
      if (fields[c].size() > kMaxCsvFieldBytes) {
        throw InputError(name, line_number, "",
                         "field " + std::to_string(c + 1) + " is " +
                             std::to_string(fields[c].size()) + " bytes long (at most " +
                             std::to_string(kMaxCsvFieldBytes) + ")");
      }
    }
    if (!have_header) {
      // A spreadsheet's export in a locale whose list separator is ';' (or a tab-separated
      // file): one column whose name holds the separator. Said as such, not as the columns
      // that are missing.
      if (fields.size() == 1) {
        const char* separator = fields[0].find(';') != std::string::npos    ? "';'"
                                : fields[0].find('\t') != std::string::npos ? "tabs"
                                                                            : nullptr;
        if (separator)
          throw InputError(name, line_number, "",
                           std::string("the header is separated by ") + separator +
                               ": rodfit reads comma-separated files with '.' as the decimal "
                               "point (export as CSV with comma delimiters)");
      }
      for (size_t c = 0; c < fields.size(); ++c) {
        if (fields[c].empty()) {
          throw InputError(name, line_number, "", "empty column name in the header");
        }
        for (size_t d = 0; d < c; ++d) {
          // Column names match regardless of case (Index), so they must differ beyond it.
          if (Lower(fields[d]) == Lower(fields[c])) {
            throw InputError(name, line_number, ClipForMessage(fields[c]),
                             "duplicate column name");
          }
        }
      }
      table.header_ = fields;
      have_header = true;
      continue;
    }
    if (fields.size() != table.header_.size()) {
      throw InputError(name, line_number, "",
                       "expected " + std::to_string(table.header_.size()) +
                           " fields as in the header, got " + std::to_string(fields.size()));
    }
    if (table.num_rows() >= kMaxCsvRows) {
      throw InputError(name, line_number, "",
                       "more than " + std::to_string(kMaxCsvRows) + " data rows (the limit)");
    }
    table.rows_.push_back(fields);
    table.lines_.push_back(line_number);
  }
  if (!have_header) throw InputError(name, 0, "", "no header row");
  return table;
}

// Motion-capture and spreadsheet exports often capitalise their headers (X, Y, Z, Frame): a
// column is found by its name in any case (the header cannot hold two names that differ only
// in case).
int CsvTable::Index(const std::string& column) const {
  const std::string wanted = Lower(column);
  for (size_t c = 0; c < header_.size(); ++c) {
    if (Lower(header_[c]) == wanted) return static_cast<int>(c);
  }
  return -1;
}

int CsvTable::RequireIndex(const std::string& column) const {
  const int c = Index(column);
  if (c < 0) {
    std::string have;
    for (const std::string& h : header_) have += (have.empty() ? "" : ",") + h;
    throw InputError(name_, 0, column, "missing column (the header has " + ClipForMessage(have, 120) + ")");
  }
  return c;
}

std::vector<double> CsvTable::Column(const std::string& column) const {
  const int c = RequireIndex(column);
  std::vector<double> values(rows_.size());
  for (size_t r = 0; r < rows_.size(); ++r) {
    const std::string& field = rows_[r][c];
    if (!ParseDouble(field, &values[r])) {
      // A field may be a megabyte of garbage: echoed cut short, so the message stays one line.
      throw InputError(name_, lines_[r], column,
                       "expected a finite number, got '" + ClipForMessage(field) + "'");
    }
  }
  return values;
}

std::vector<std::string> CsvTable::TextColumn(const std::string& column) const {
  const int c = RequireIndex(column);
  std::vector<std::string> values;
  values.reserve(rows_.size());
  for (const auto& row : rows_) values.push_back(row[c]);
  return values;
}

bool ParseDouble(const std::string& text, double* value) {
  const char* begin = text.data();
  const char* end = begin + text.size();
  if (begin != end && *begin == '+') ++begin;  // from_chars rejects a leading '+'
  const auto result = std::from_chars(begin, end, *value);
  return result.ec == std::errc() && result.ptr == end && std::isfinite(*value);
}

std::string FormatDouble(double value) {
  char buffer[32];
  if (value == 0.0) value = 0.0;  // no "-0" in data files
  std::snprintf(buffer, sizeof(buffer), "%.17g", value);
  return buffer;
}

void WriteFileAtomically(const std::string& path, const std::string& contents) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const std::string base = target.filename().string();
  if (base.empty() || base == "." || base == "..") {
    throw InputError(path, 0, "", "not a file name");
  }
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");

  // A name no other writer uses: O_EXCL fails rather than sharing a file with another process.
  static std::atomic<unsigned> counter{0};
  std::string temp;
  int fd = -1;
  for (int attempt = 0; attempt < 100 && fd < 0; ++attempt) {
    temp = (dir /
            ("." + base + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++)))
               .string();
    fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0 && errno != EEXIST) {
      throw InputError(path, 0, "", "cannot write: " + ErrnoMessage(errno));
    }
  }
  if (fd < 0) throw InputError(path, 0, "", "cannot write: no free temporary file name");

  auto fail = [&](const std::string& what, int err) {
    if (fd >= 0) ::close(fd);
    ::unlink(temp.c_str());
    throw InputError(path, 0, "", what + ": " + ErrnoMessage(err));
  };
  size_t written = 0;
  while (written < contents.size()) {
    const ssize_t n = ::write(fd, contents.data() + written, contents.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("cannot write", errno);
    }
    written += static_cast<size_t>(n);
  }
  // No fsync: this guards readers and failed runs against partial files, not power loss.
  const int closed = ::close(fd);
  fd = -1;
  if (closed != 0) fail("cannot write", errno);
  if (std::rename(temp.c_str(), path.c_str()) != 0) fail("cannot replace", errno);
}

void CreateDirectories(const std::string& dir) {
  namespace fs = std::filesystem;
  if (dir.empty()) throw InputError("output directory", 0, "", "empty name");
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw InputError(dir, 0, "", "cannot create directory: " + ec.message());
  if (!fs::is_directory(dir, ec)) throw InputError(dir, 0, "", "not a directory");
}

}  // namespace rodfit
