// The archive a configuration's settings are visited on (Ceres' and COLMAP's pattern of one
// declaration per option): each configuration has a `Serialize(SettingsArchive*, Config*)`
// beside it that visits its fields — the key, the field (its initializer is the default) and
// the range — and, for a setting the command line takes, the option's name and help text
// (Describe). The archives that run these visitors are the experiment reader's (rodfit/io/
// settings.h: a YAML block, errors at file:line:key), the command line's (src/cli/
// cli_settings.h: CLI11 options), the runtime's option check, and the tests that hold every
// key's documentation row to its declaration. Standard library only, so that every layer,
// the runtime included, can declare its settings here.
#pragma once

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfit {

class SettingsArchive {
 public:
  virtual ~SettingsArchive() = default;
  /// Reading values (from a block or a command line); otherwise only the keys and their ranges
  /// are visited (the values are the defaults).
  virtual bool reading() const = 0;
  /// An integer in [lo, hi] ("must be an integer in [lo, hi]").
  virtual void Integer(const char* key, int* value, int lo, int hi) = 0;
  /// An integer, then in [lo, hi] ("expected an integer", then "must be in [lo, hi]").
  virtual void Count(const char* key, int* value, int lo, int hi) = 0;
  /// A number in [lo, hi] ([s], [1], ... as the key's row says).
  virtual void Number(const char* key, double* value, double lo, double hi) = 0;
  /// A number > 0.
  virtual void Positive(const char* key, double* value) = 0;
  virtual void Bool(const char* key, bool* value) = 0;
  /// One of `words`: *index becomes its position. `expected` is the message of another word
  /// (e.g. "must be explicit, implicit, backward_euler, midpoint or bdf2").
  virtual void Choice(const char* key, int* index, const std::vector<std::string>& words,
                      const std::string& expected) = 0;
  /// A list of integers (a command line's comma-separated list). An archive that has no such
  /// values (a YAML settings block) refuses the declaration: a programming error.
  virtual void IntegerList(const char* key, std::vector<int>* value) {
    (void)value;
    throw std::logic_error(std::string("SettingsArchive: ") + key +
                           ": this archive has no integer lists");
  }
  /// A key the block must give.
  virtual void Require(const char* key) = 0;
  /// Whether the block gives the key.
  virtual bool Has(const char* key) const = 0;
  /// Reading: an error at `key` unless `ok` (at the block when it does not give the key).
  virtual void Check(bool ok, const char* key, const std::string& message) = 0;
  /// The next key visited is `key`, which the command line takes as `option` (e.g. "--smooth";
  /// its own spelling where it differs from the key) with this help text. Declared right
  /// before the key's visit, so that its name, default, range and help are declared together.
  /// A key without one is not a command-line option. Archives other than the command line's
  /// and the documentation's ignore it.
  virtual void Describe(const char* key, const char* option, const std::string& help) {
    (void)key, (void)option, (void)help;
  }
  /// The next key visited is `key`, which a fit's profile carries as `profile_key` in its `fit`
  /// object (docs/formats.md, "Profile JSON"; the setting the fit ran with, e.g. its loss).
  /// Declared right before the key's visit, as Describe. Archives other than the profile
  /// writer's ignore it.
  virtual void Carry(const char* key, const char* profile_key) { (void)key, (void)profile_key; }
};

/// A configuration's values held to their declared ranges (a library caller's options, checked
/// by the declaration the files and the command line are read with): the first setting outside
/// its range, as `key must be in [lo, hi] (is v)`, `key must be > 0 (is v)` or `key ` and the
/// visitor's own check's message. Usage: `SettingsCheck c; Serialize(&c, &copy); c.ok()`.
class SettingsCheck final : public SettingsArchive {
 public:
  bool ok() const { return why_.empty(); }
  const std::string& why() const { return why_; }

  bool reading() const override { return true; }
  void Integer(const char* key, int* value, int lo, int hi) override {
    if (*value < lo || *value > hi)
      Fail(key, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "] (is " +
                    std::to_string(*value) + ")");
  }
  void Count(const char* key, int* value, int lo, int hi) override { Integer(key, value, lo, hi); }
  void Number(const char* key, double* value, double lo, double hi) override {
    if (!(*value >= lo && *value <= hi))
      Fail(key, "must be in [" + Show(lo) + ", " + Show(hi) + "] (is " + Show(*value) + ")");
  }
  void Positive(const char* key, double* value) override {
    if (!(*value > 0.0) || !std::isfinite(*value))
      Fail(key, "must be > 0 (is " + Show(*value) + ")");
  }
  void Bool(const char*, bool*) override {}
  void Choice(const char* key, int* index, const std::vector<std::string>& words,
              const std::string& expected) override {
    if (*index < 0 || *index >= static_cast<int>(words.size())) Fail(key, expected);
  }
  void IntegerList(const char*, std::vector<int>*) override {}
  void Require(const char*) override {}
  bool Has(const char*) const override { return true; }
  void Check(bool ok, const char* key, const std::string& message) override {
    if (!ok) Fail(key, message);
  }

 private:
  static std::string Show(double v) {
    char text[32];
    std::snprintf(text, sizeof(text), "%.10g", v);
    return text;
  }
  void Fail(const char* key, const std::string& message) {
    if (why_.empty()) why_ = std::string(key) + " " + message;
  }
  std::string why_;
};

}  // namespace rodfit
