// A configuration's settings as command-line options (rodfit/model/settings_archive.h): the
// options are made from the configuration's Serialize — each key the visitor describes with an
// option name and help text becomes that option, checked by the key's range or words — and the
// parsed values are read back through the same visitor. A setting's name, default, range and
// help are thus declared once, beside its configuration; the command only places each option
// in its help (Add) and reads the values (Read).
#pragma once

#include <functional>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "rodfit/model/settings_archive.h"

class CliSettings final : public rodfit::SettingsArchive {
 public:
  /// Declares the options of the settings `visit` visits (on its configurations' defaults).
  explicit CliSettings(const std::function<void(rodfit::SettingsArchive*)>& visit);

  /// Adds the option of `key` to `app` here (the help lists options in the order they are
  /// added). Throws std::logic_error for a key without an option, or one added twice.
  void Add(CLI::App* app, const char* key);
  /// Throws std::logic_error unless every described option was added: a setting declared with
  /// an option must be one.
  void CheckAllAdded() const;

  /// After parsing: reads the given options into a configuration through its visitor (the
  /// others keep their values). A list that does not parse is std::invalid_argument naming the
  /// option.
  void Read(const std::function<void(rodfit::SettingsArchive*)>& visit);

  bool reading() const override { return reading_; }
  void Integer(const char* key, int* value, int lo, int hi) override;
  void Count(const char* key, int* value, int lo, int hi) override;
  void Number(const char* key, double* value, double lo, double hi) override;
  void Positive(const char* key, double* value) override;
  void Bool(const char* key, bool* value) override;
  void Choice(const char* key, int* index, const std::vector<std::string>& words,
              const std::string& expected) override;
  void IntegerList(const char* key, std::vector<int>* value) override;
  void Require(const char* key) override;
  bool Has(const char* key) const override;
  void Check(bool ok, const char* key, const std::string& message) override;
  void Describe(const char* key, const char* option, const std::string& help) override;

 private:
  // One option: its name, help, the value CLI11 parses into, and how to add it to an app.
  struct Slot {
    std::string option, help;
    int integer = 0;
    double number = 0.0;
    bool flag = false;
    std::string text;
    std::vector<std::string> words;
    std::function<void(CLI::App*, Slot*)> add;
    CLI::Option* added = nullptr;
  };
  // Declaring: the slot of a described key (nullptr when it has no option); reading: the slot
  // of a given option (nullptr when not given).
  Slot* Declare(const char* key);
  const Slot* Given(const char* key) const;

  bool reading_ = false;
  std::string described_key_;
  Slot described_;
  std::map<std::string, Slot> slots_;  // node-stable: CLI11 holds pointers into the slots
};
