// `stampede metadetect`: metadetection of image files (app/metadetect_run). The parsing and the
// reporting are shared with `stampede-mpi metadetect`.
#pragma once

#include "app/metadetect_run.hpp"

struct MetadetectCommandLine {
  stampede::app::MetadetectRunOptions run;
  bool quiet = false;
};

// Parses `metadetect ARGS` (argv[0] the command's name): -1 to run, else the exit code (--help
// printed when `print`). Throws std::invalid_argument naming the option.
int parse_metadetect_arguments(int argc, char** argv, MetadetectCommandLine* command, bool print);

// Runs with a progress line and the summary on stderr; the exit code.
int run_metadetect_with_reports(const MetadetectCommandLine& command);

int run_metadetect_command(int argc, char** argv);
