// Settings as command-line options (cli_settings.h).
#include "cli_settings.h"

#include <sstream>
#include <stdexcept>

#include "cli_common.h"
#include "rodfit/io/csv.h"

CliSettings::CliSettings(const std::function<void(rodfit::SettingsArchive*)>& visit) {
  visit(this);
  if (!described_key_.empty())
    throw std::logic_error("CliSettings: " + described_key_ + " described but not visited");
}

void CliSettings::Add(CLI::App* app, const char* key) {
  const auto it = slots_.find(key);
  if (it == slots_.end() || it->second.added)
    throw std::logic_error(std::string("CliSettings: ") + key +
                           (it == slots_.end() ? " has no option" : " added twice"));
  it->second.add(app, &it->second);
}

void CliSettings::CheckAllAdded() const {
  for (const auto& [key, slot] : slots_)
    if (!slot.added)
      throw std::logic_error("CliSettings: " + key + " (" + slot.option + ") was not added");
}

void CliSettings::Read(const std::function<void(rodfit::SettingsArchive*)>& visit) {
  reading_ = true;
  visit(this);
  reading_ = false;
}

CliSettings::Slot* CliSettings::Declare(const char* key) {
  if (described_key_.empty()) return nullptr;  // not a command-line option
  if (described_key_ != key)
    throw std::logic_error("CliSettings: " + described_key_ + " described, " + key + " visited");
  described_key_.clear();
  Slot& slot = slots_[key];
  slot = described_;
  return &slot;
}

const CliSettings::Slot* CliSettings::Given(const char* key) const {
  const auto it = slots_.find(key);
  if (it == slots_.end() || !it->second.added || it->second.added->count() == 0) return nullptr;
  return &it->second;
}

void CliSettings::Describe(const char* key, const char* option, const std::string& help) {
  if (reading_) return;
  if (!described_key_.empty())
    throw std::logic_error("CliSettings: " + described_key_ + " described but not visited");
  described_key_ = key;
  described_ = Slot();
  described_.option = option;
  described_.help = help;
}

void CliSettings::Integer(const char* key, int* value, int lo, int hi) {
  if (reading_) {
    if (const Slot* s = Given(key)) *value = s->integer;
  } else if (Slot* s = Declare(key)) {
    s->add = [lo, hi](CLI::App* app, Slot* slot) {
      slot->added = app->add_option(slot->option, slot->integer, slot->help)
                        ->check(CLI::Range(lo, hi));
    };
  }
}

void CliSettings::Count(const char* key, int* value, int lo, int hi) {
  Integer(key, value, lo, hi);
}

void CliSettings::Number(const char* key, double* value, double lo, double hi) {
  if (reading_) {
    if (const Slot* s = Given(key)) *value = s->number;
  } else if (Slot* s = Declare(key)) {
    // Finite as well as in range: CLI::Range lets "nan" through (cli_common.h).
    s->add = [lo, hi](CLI::App* app, Slot* slot) {
      slot->added = app->add_option(slot->option, slot->number, slot->help)
                        ->check(FiniteRange(lo, hi));
    };
  }
}

void CliSettings::Positive(const char* key, double* value) {
  if (reading_) {
    if (const Slot* s = Given(key)) *value = s->number;
  } else if (Slot* s = Declare(key)) {
    s->add = [](CLI::App* app, Slot* slot) {
      slot->added = app->add_option(slot->option, slot->number, slot->help)
                        ->check(FiniteRange(std::numeric_limits<double>::denorm_min(),
                                            std::numeric_limits<double>::max()));
    };
  }
}

void CliSettings::Bool(const char* key, bool* value) {
  if (reading_) {
    if (const Slot* s = Given(key)) *value = s->flag;
  } else if (Slot* s = Declare(key)) {
    s->add = [](CLI::App* app, Slot* slot) {
      slot->added = app->add_flag(slot->option, slot->flag, slot->help);
    };
  }
}

void CliSettings::Choice(const char* key, int* index, const std::vector<std::string>& words,
                         const std::string& expected) {
  (void)expected;  // CLI11's IsMember names the words
  if (reading_) {
    if (const Slot* s = Given(key))
      for (size_t k = 0; k < words.size(); ++k)
        if (words[k] == s->text) *index = static_cast<int>(k);
  } else if (Slot* s = Declare(key)) {
    s->words = words;
    s->add = [](CLI::App* app, Slot* slot) {
      slot->added = app->add_option(slot->option, slot->text, slot->help)
                        ->check(CLI::IsMember(slot->words));
    };
  }
}

void CliSettings::IntegerList(const char* key, std::vector<int>* value) {
  if (reading_) {
    const Slot* s = Given(key);
    if (!s) return;
    value->clear();
    std::stringstream list(s->text);
    std::string item;
    while (std::getline(list, item, ',')) {
      double v = 0.0;
      if (!rodfit::ParseDouble(item, &v) || v != static_cast<int>(v))
        throw std::invalid_argument(s->option + ": not an integer: '" + item.substr(0, 40) + "'");
      value->push_back(static_cast<int>(v));
    }
  } else if (Slot* s = Declare(key)) {
    s->add = [](CLI::App* app, Slot* slot) {
      slot->added = app->add_option(slot->option, slot->text, slot->help);
    };
  }
}

void CliSettings::Require(const char* key) {
  if (!reading_) return;
  const auto it = slots_.find(key);
  if (it != slots_.end() && !Given(key))
    throw std::invalid_argument(it->second.option + " is required");
}

bool CliSettings::Has(const char* key) const { return reading_ && Given(key) != nullptr; }

void CliSettings::Check(bool ok, const char* key, const std::string& message) {
  if (!reading_ || ok) return;
  const auto it = slots_.find(key);
  throw std::invalid_argument((it != slots_.end() ? it->second.option : std::string(key)) + " " +
                              message);
}
