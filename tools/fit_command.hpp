// `stampede fit`: fits every object of a stamp grid or an image + catalogue and writes one row
// per object to a FITS table, with crash-safe resume. The command parses its arguments and
// prints; the run itself is app::FitRun.
#pragma once

#include "app/fit_run.hpp"

int run_fit_command(int argc, char** argv);

// The command in two steps, for the MPI driver (tools/mpi_main.cpp), which runs the same command.
// Parses the arguments into *run (ini loaded, --set applied); returns -1 to go on, else the exit
// code (0 after --help or --help-config, 2 after a usage message). Throws for bad arguments.
int parse_fit_arguments(int argc, char** argv, stampede::app::FitRunOptions* run);
// Runs it with progress and the summary on stderr (unless --quiet); returns the exit code.
int run_fit_with_reports(stampede::app::FitRunOptions& run);
