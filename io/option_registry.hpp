// An option registry: the text side of a typed configuration (text <-> values). Each key is one
// entry holding its name, help, section, parser and printer over the configuration's field, so
// defaults, parsing, documentation and the output header cannot disagree. Values print in a
// canonical form that parses back to the identical value (io/option_text.hpp).
//
// The configuration type is the caller's (app/run_config's RunConfig); it needs a member
// `std::map<std::string, std::string> explicitly_set`: each key given, with where ("FILE:LINE" for
// an ini file, "--set" for the command line, "" for set()).
//
// Ini syntax: `key = value` per line; `#` starts a comment (whole line or trailing, so values cannot
// contain '#'); blank lines allowed; surrounding whitespace trimmed; `[section]` lines ignored (the
// keys are global); a key given twice in one file is an error. Keys are case-sensitive; enum and
// boolean values are not (their parsers say so).
#pragma once

#include <algorithm>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "engine/common/quoted_value.hpp"
#include "io/config_error.hpp"
#include "io/header_value.hpp"
#include "io/option_text.hpp"
#include "io/text_lines.hpp"

namespace stampede::io {

struct OptionInfo {
  std::string name;
  std::string default_value;  // canonical text of the default
  std::string help;
  HeaderValueType type = HeaderValueType::kText;  // the value's type as a header card
};

template <class Config>
struct OptionEntry {
  std::string name;
  std::string help;
  std::string section;  // heading in the template
  std::function<std::string(const Config&)> get;
  std::function<std::string(Config&, const std::string&)> set;  // "" on success, else why not
  HeaderValueType type = HeaderValueType::kText;
};

// Entries of the common kinds. `access` is a generic lambda `[](auto& c) -> auto& { return
// c.field; }`, so one accessor serves both the const getter and the setter.
template <class Config, class Access>
OptionEntry<Config> int_option(const char* section, const char* name, const char* help, Access access) {
  return {name, help, section, [access](const Config& c) { return std::to_string(access(c)); },
          [access](Config& c, const std::string& v) {
            int x = 0;
            std::string why = parse_integer(v, &x);
            if (why.empty()) access(c) = x;
            return why;
          },
          HeaderValueType::kInteger};
}

template <class Config, class Access>
OptionEntry<Config> double_option(const char* section, std::string name, std::string help, DoubleKind kind,
                                  Access access) {
  return {std::move(name), std::move(help), section, [access](const Config& c) { return format_double(access(c)); },
          [access, kind](Config& c, const std::string& v) {
            double x = 0;
            std::string why = parse_double(v, kind, &x);
            if (why.empty()) access(c) = x;
            return why;
          },
          HeaderValueType::kReal};
}

template <class Config, class Access>
OptionEntry<Config> bool_option(const char* section, std::string name, std::string help, Access access) {
  return {std::move(name), std::move(help), section, [access](const Config& c) { return format_bool(access(c)); },
          [access](Config& c, const std::string& v) {
            bool x = false;
            std::string why = parse_bool(v, &x);
            if (why.empty()) access(c) = x;
            return why;
          }};
}

template <class Config, class Access>
OptionEntry<Config> string_option(const char* section, const char* name, const char* help, Access access) {
  return {name, help, section, [access](const Config& c) { return std::string(access(c)); },
          [access](Config& c, const std::string& v) {
            access(c) = v;
            return std::string();
          }};
}

template <class Config>
class OptionRegistry {
 public:
  explicit OptionRegistry(std::vector<OptionEntry<Config>> entries) : entries_(std::move(entries)) {}
  const std::vector<OptionEntry<Config>>& entries() const { return entries_; }

  const OptionEntry<Config>* find(const std::string& key) const {
    for (const auto& e : entries_)
      if (e.name == key) return &e;
    return nullptr;
  }

  // "unknown option 'KEY'", with a suggestion when a key is at most two edits away.
  ConfigError unknown(const std::string& key) const {
    std::string msg = "unknown option " + quoted_value(key);
    const OptionEntry<Config>* best = nullptr;
    std::size_t best_d = 3;
    for (const auto& e : entries_) {
      const std::size_t d = edit_distance(lower(key), lower(e.name));
      if (d < best_d) best = &e, best_d = d;
    }
    if (best) msg += " (did you mean '" + best->name + "'?)";
    return ConfigError(msg);
  }

  // Sets one key from text and records it in explicitly_set. Throws ConfigError
  // "option 'KEY' = 'VALUE': <why>" for a value that does not parse, and unknown() for an unknown
  // key. On error the config is unchanged.
  void set(Config& config, const std::string& key, const std::string& value) const {
    const auto* e = find(key);
    if (!e) throw unknown(key);
    const std::string why = e->set(config, value);
    if (!why.empty()) throw ConfigError("option " + quoted_value(key) + " = " + quoted_value(value) + ": " + why);
    config.explicitly_set[key] = "";
  }

  // The canonical text of a key's value; set(get(c, k)) reproduces it exactly.
  std::string get(const Config& config, const std::string& key) const {
    const auto* e = find(key);
    if (!e) throw unknown(key);
    return e->get(config);
  }

  // Reads an ini file into config, all or nothing. Errors name the file and line.
  void load_ini(Config& config, const std::string& path) const {
    std::ifstream in(path);
    if (!in) throw ConfigError("cannot read config file '" + path + "'");
    Config updated = config;
    std::map<std::string, int> line_of;  // key -> line that set it, to reject repeats
    std::string line;
    for (int number = 1;; ++number) {
      const TextLine read = read_text_line(in, &line);
      if (read == TextLine::kEnd) break;
      const std::string where = path + ":" + std::to_string(number);
      if (read == TextLine::kTooLong)
        throw ConfigError(where + ": a line longer than " + std::to_string(kMaxTextLine) +
                          " bytes: not a configuration file");
      if (number == 1 && line.starts_with("\xEF\xBB\xBF")) line.erase(0, 3);  // UTF-8 byte-order mark
      const std::string text = trim(std::string_view(line).substr(0, line.find('#')));
      if (text.empty() || (text.front() == '[' && text.back() == ']')) continue;
      const std::size_t eq = text.find('=');
      const std::string key = eq == std::string::npos ? "" : trim(std::string_view(text).substr(0, eq));
      if (key.empty()) throw ConfigError(where + ": expected 'key = value'");
      if (auto [it, fresh] = line_of.emplace(key, number); !fresh)
        throw ConfigError(where + ": option " + quoted_value(key) + " is set twice (first on line " +
                          std::to_string(it->second) + ")");
      try {
        set(updated, key, trim(std::string_view(text).substr(eq + 1)));
      } catch (const ConfigError& e) {
        throw ConfigError(where + ": " + e.what());
      }
      updated.explicitly_set[key] = where;
    }
    if (in.bad()) throw ConfigError("cannot read config file '" + path + "'");  // e.g. a directory
    config = std::move(updated);
  }

  // One `key=value` from the command line (split at the first '=', both sides trimmed); errors are
  // set()'s prefixed by "--set key=value: ".
  void apply_set(Config& config, const std::string& assignment) const {
    const std::size_t eq = assignment.find('=');
    const std::string key = eq == std::string::npos ? "" : trim(std::string_view(assignment).substr(0, eq));
    if (key.empty()) throw ConfigError("--set " + quoted_value(assignment) + ": expected key=value");
    try {
      set(config, key, trim(std::string_view(assignment).substr(eq + 1)));
    } catch (const ConfigError& e) {
      throw ConfigError("--set " + quoted_value(assignment) + ": " + e.what());
    }
    config.explicitly_set[key] = "--set";
  }

  // Every key with its value, in registry order.
  std::vector<std::pair<std::string, std::string>> effective(const Config& config) const {
    std::vector<std::pair<std::string, std::string>> out;
    out.reserve(entries_.size());
    for (const auto& e : entries_) out.emplace_back(e.name, e.get(config));
    return out;
  }

  // Every key with its default, help and header type.
  std::vector<OptionInfo> options() const {
    const Config defaults;
    std::vector<OptionInfo> out;
    for (const auto& e : entries_) out.push_back({e.name, e.get(defaults), e.help, e.type});
    return out;
  }

  // An ini file documenting every option after `preamble`: a comment with its help, then
  // `#key = default`, commented out so that loading the template changes nothing.
  std::string ini_template(std::string preamble) const {
    const Config defaults;
    std::string section;
    for (const auto& e : entries_) {
      if (e.section != section) {
        section = e.section;
        preamble += "\n# --- " + section + " ---\n";
      }
      const std::string value = e.get(defaults);
      preamble += "# " + e.help + "\n#" + e.name + (value.empty() ? " =" : " = " + value) + "\n";
    }
    return preamble;
  }

 private:
  std::vector<OptionEntry<Config>> entries_;
};

}  // namespace stampede::io
