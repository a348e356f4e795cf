// The options of a metadetection, one entry each: the field (its name in engine/ messages, which
// is also the Python keyword), the command-line flag, the header key that records it and its type,
// how a value is read and recorded, and its help. The command line (tools/metadetect_command),
// the table's header keys and the run's fingerprint (app/metadetect_run) and Python's keywords
// (python/src/metadetect_bindings) are all made from this one table, so they cannot disagree.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "engine/metadetect/metadetect_options.hpp"
#include "io/header_value.hpp"

namespace stampede::app {

struct MetadetectOptionKey {
  enum class Kind { kInteger, kReal, kSwitch, kChoice };
  std::string field;   // "cell_size": MetadetectOptions::IsValid's name for it; the Python keyword
  std::string flag;    // "--cell-size"; "" none (recorded only)
  std::string metavar;  // "N"; "" for a switch
  std::string header;  // "CELLSIZE"
  Kind kind = Kind::kInteger;
  bool switch_sets = true;  // a switch: the value its flag sets ("--no-fixnoise" sets false)
  // The header's text of the option's value (reals the shortest text that reads back bitwise).
  std::function<std::string(const MetadetectOptions&)> recorded;
  // Sets the option from text ("true"/"false" for a switch); "" or why not.
  std::function<std::string(MetadetectOptions&, std::string_view)> set;
  std::string help;  // for --help and the docstring; "%s" stands for the default's recorded text
  bool python() const { return !flag.empty(); }
  io::HeaderValueType header_type() const;
};

const std::vector<MetadetectOptionKey>& metadetect_option_keys();

// The header keys that record `options`, in the table's order (what identifies the run).
std::vector<std::pair<std::string, std::string>> metadetect_header_keys(const MetadetectOptions& options);
// Their types, for the header's number cards.
std::map<std::string, io::HeaderValueType> metadetect_header_types();

// An engine message naming fields ("cell_size = 3: must be ...", as MetadetectOptions::IsValid
// writes them) with the fields replaced by their command-line flags ("--cell-size = 3: ..."): the
// core names fields, the command line speaks flags. Translated: the field the message opens with,
// and fields of two words or more anywhere in it.
std::string with_metadetect_flags(std::string message);

}  // namespace stampede::app
