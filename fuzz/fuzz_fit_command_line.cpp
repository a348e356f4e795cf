// Fuzz target: the `stampede fit` command line (tools/fit_command: every option, --shard, --threads,
// --set through app::apply_set, the cross-option refusals) and the --input-list file
// (app/input_list). The input is the argument vector, arguments separated by NUL bytes, then after a
// 0x01 byte the list file's text. --config is dropped (the ini parser has fuzz_run_config), so the
// run reads no path the input names. An accepted command line must hold what the parser promises
// (a shard with 0 <= I < N <= 1000000, threads within the one rule, a valid configuration or a
// ConfigError); an accepted list must give distinct outputs, one per input: else abort, a finding.
#include <algorithm>
#include <cstdlib>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/fit_run.hpp"
#include "app/input_list.hpp"
#include "fuzz/fuzz_file.hpp"
#include "app/run_config.hpp"
#include "tools/fit_command.hpp"

namespace {

void check_list(const std::string& text, const std::string& output_dir) {
  const stampede::fuzz::FuzzFile list({reinterpret_cast<const unsigned char*>(text.data()), text.size()});
  std::vector<stampede::app::ListedInput> inputs;
  try {
    inputs = stampede::app::read_input_list(list.path(), output_dir);
  } catch (const stampede::io::ConfigError&) {
    return;
  }
  if (inputs.empty()) std::abort();
  std::set<std::string> outputs;
  for (const auto& input : inputs) {
    if (input.input.empty() || input.input.find('#') != std::string::npos) std::abort();
    if (!outputs.insert(input.output).second) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  const std::size_t split = std::min(bytes.find('\x01'), bytes.size());
  std::vector<std::string> args{"fit"};
  for (std::size_t begin = 0; begin <= split;) {
    const std::size_t end = std::min(bytes.find('\0', begin), split);
    std::string arg = bytes.substr(begin, end - begin);
    if (arg == "--config") arg = "--quiet";
    args.push_back(std::move(arg));
    begin = end + 1;
  }
  if (args.size() > 64) args.resize(64);
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  FitCommandLine command;
  int code = 0;
  try {
    code = parse_fit_arguments(static_cast<int>(args.size()), argv.data(), &command, false);
  } catch (const std::invalid_argument&) {
    return 0;
  } catch (const stampede::io::ConfigError&) {
    return 0;
  }
  if (code != -1 && code != 0 && code != 2) std::abort();
  if (code != -1) return 0;
  const auto& run = command.run;
  if (run.output.empty() || (run.input.empty() && run.meds.empty() && command.input_list.empty())) std::abort();
  if (run.shards < 1 || run.shards > 1000000 || run.shard < 0 || run.shard >= run.shards) std::abort();
  try {
    stampede::app::check_threads(run.threads, "--threads");
  } catch (const stampede::io::ConfigError&) {
    std::abort();  // the parser let through a thread count the one rule refuses
  }
  if (run.shards > 1) {
    const auto again = stampede::app::parse_shard(std::to_string(run.shard) + "/" + std::to_string(run.shards));
    if (!again || again->first != run.shard || again->second != run.shards) std::abort();
  }
  try {
    stampede::app::validate(run.config);
  } catch (const stampede::io::ConfigError&) {
  }
  if (!command.input_list.empty() && split < bytes.size()) check_list(bytes.substr(split + 1), run.output);
  return 0;
}
