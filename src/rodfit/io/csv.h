// CSV tables as docs/formats.md defines them (a header row, columns by name, extra columns
// ignored), atomic file output (never leave a half-written file) and the one number
// format every rodfit output uses. Errors are InputErrors naming the file, line and column.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace rodfit {

/// Input files are bounded before they are parsed (docs/formats.md, "Limits"): at most this many
/// bytes (experiment YAML, CSV, image files), regular files only.
constexpr std::uintmax_t kMaxInputFileBytes = std::uintmax_t{256} << 20;  // 256 MiB
/// At most this many data rows in a CSV file, and this many bytes in one field.
constexpr int kMaxCsvRows = 1000000;
constexpr size_t kMaxCsvFieldBytes = size_t{4} << 20;  // 4 MiB

/// Throws InputError naming `path` unless it is a regular file (not a directory, device, FIFO or
/// socket) of at most `max_bytes`; `what` names the kind of file for the message ("a CSV file").
/// Opens nothing, so a FIFO cannot block.
void CheckInputFile(const std::string& path, const std::string& what,
                    std::uintmax_t max_bytes = kMaxInputFileBytes);

/// The whole of an input file checked by CheckInputFile, read without ever holding more than
/// `max_bytes` + 1 bytes (a file that grows meanwhile is refused as too large).
std::string ReadInputFile(const std::string& path, const std::string& what,
                          std::uintmax_t max_bytes = kMaxInputFileBytes);

/// A CSV file read whole: comma separated, fields trimmed of blanks, double-quoted fields
/// ("" inside is a quote), blank lines and lines starting with '#' skipped, CRLF and a UTF-8
/// byte-order mark accepted. Every row must have as many fields as the header.
class CsvTable {
 public:
  /// Reads and parses a file (ReadInputFile: a regular file of at most kMaxInputFileBytes);
  /// throws InputError if it cannot be read, is malformed, or has more than kMaxCsvRows rows or
  /// a field longer than kMaxCsvFieldBytes.
  static CsvTable Read(const std::string& path);
  /// Parses text; `name` is the file name used in error messages.
  static CsvTable Parse(const std::string& text, const std::string& name);

  const std::string& name() const { return name_; }
  const std::vector<std::string>& header() const { return header_; }
  int num_rows() const { return static_cast<int>(rows_.size()); }
  /// 1-based line of row r in the file (for callers' own error messages).
  int line(int r) const { return lines_[r]; }

  bool HasColumn(const std::string& column) const { return Index(column) >= 0; }
  /// The column's values as finite numbers. Throws InputError naming the file and column when
  /// it is missing, and the row's line when a field is not a number or not finite.
  std::vector<double> Column(const std::string& column) const;
  /// The column's fields as text; throws InputError when it is missing.
  std::vector<std::string> TextColumn(const std::string& column) const;

 private:
  int Index(const std::string& column) const;
  int RequireIndex(const std::string& column) const;

  std::string name_;
  std::vector<std::string> header_;
  std::vector<std::vector<std::string>> rows_;
  std::vector<int> lines_;
};

/// Parses a whole field as a finite double (no locale, no trailing characters). Returns false
/// otherwise.
bool ParseDouble(const std::string& text, double* value);

/// `%.17g`: enough digits that reading the text back gives the same double.
std::string FormatDouble(double value);

/// Writes `contents` to a new temporary file beside `path`, then renames it over `path`, so a
/// reader sees the old file or the whole new one, never a part. Throws InputError naming `path`
/// (and leaves no temporary file) when the directory is missing or not writable.
void WriteFileAtomically(const std::string& path, const std::string& contents);

/// mkdir -p. Throws InputError naming `dir` when it cannot be created or is not a directory.
void CreateDirectories(const std::string& dir);

}  // namespace rodfit
