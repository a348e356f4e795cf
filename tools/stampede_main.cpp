// The `stampede` command: dispatches to sub-commands.
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>

#include "app/version.hpp"
#include "io/durable_file.hpp"
#include "tools/demo_command.hpp"
#include "tools/ring_command.hpp"
#include "tools/fit_command.hpp"
#include "tools/merge_command.hpp"
#include "tools/metadetect_command.hpp"
#include "tools/metrics_command.hpp"
#include "tools/sim_command.hpp"
#include "tools/calibrate_command.hpp"

namespace {

void print_usage(std::FILE* out) {
  std::fprintf(out,
               "stampede: galaxy shape measurement for weak lensing (the im3shape method)\n"
               "\n"
               "usage: stampede <command> [options]\n"
               "       stampede --version\n"
               "\n"
               "commands:\n"
               "  fit      fit every object of a stamp grid or image + catalogue; write a FITS table\n"
               "  merge    join the tables of a job array's `fit --shard I/N` runs into one\n"
               "  metadetect  metadetection of images: detect and measure on each metacal image of each cell\n"
               "  metrics  shear biases m, c and the GREAT08 Q from fit tables and truth files\n"
               "  demo     fit the bundled noise-free GREAT08-like set and print true vs recovered e\n"
               "  ring     noise-free ring-test studies of the im3shape paper (figures 2, 4, 5, 6)\n"
               "  sim      simulations: GREAT08-like sets (sim great08), MEDS tiles (sim meds),\n"
               "           metadetection test cells (sim cells)\n"
               "  calibrate  noise-bias calibration: build a table from simulations, apply it to a catalogue\n"
               "\n"
               "Run 'stampede <command> --help' for a command's options.\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    print_usage(argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  if (!std::strcmp(argv[1], "--version")) {
    std::printf("stampede %.*s\n", static_cast<int>(stampede::app::program_version().size()),
                stampede::app::program_version().data());
    return 0;
  }
  const std::string command = argv[1];
  // Every command writes files: past `ulimit -f` a write then fails with a message saying so,
  // instead of SIGXFSZ ending the process with none (and an output that looks merely cut short).
  stampede::io::ignore_file_size_signal();
  try {
    if (command == "fit") return run_fit_command(argc - 1, argv + 1);
    if (command == "merge") return run_merge_command(argc - 1, argv + 1);
    if (command == "metadetect") return run_metadetect_command(argc - 1, argv + 1);
    if (command == "metrics") return run_metrics_command(argc - 1, argv + 1);
    if (command == "demo") return run_demo_command(argc - 1, argv + 1);
    if (command == "ring") return run_ring_command(argc - 1, argv + 1);
    if (command == "sim") return run_sim_command(argc - 1, argv + 1);
    if (command == "calibrate") return run_calibrate_command(argc - 1, argv + 1);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "stampede %s: error: %s\n", command.c_str(), e.what());
    return 1;
  }
  std::fprintf(stderr, "stampede: unknown command '%s'\n\n", command.c_str());
  print_usage(stderr);
  return 2;
}
