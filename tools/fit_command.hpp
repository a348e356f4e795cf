// `stampede fit`: fits every object of a stamp grid or an image + catalogue and writes one row
// per object to a FITS table, with crash-safe resume. The command parses its arguments and
// prints; the run itself is app::FitRun.
#pragma once

#include "app/fit_run.hpp"

int run_fit_command(int argc, char** argv);

#include <string>
#include <vector>

#include "app/input_list.hpp"

// The command in steps, for the MPI driver (tools/mpi/mpi_main.cpp), which runs the same command.
struct FitCommandLine {
  stampede::app::FitRunOptions run;  // with --input-list: no input, and output the directory
  std::string input_list;            // --input-list FILE, or ""
};
// Parses the arguments (ini loaded, --set applied); returns -1 to go on, else the exit code (0
// after --help or --help-config, 2 after a usage message). Throws for bad arguments. `messages`
// false: the help and usage texts are not printed (the MPI driver's ranks other than 0).
int parse_fit_arguments(int argc, char** argv, FitCommandLine* command, bool messages = true);
// Runs the parsed command: its input, or each of its list's inputs in turn (skipped when its output
// is complete and --resume is given, resumed when it has a checkpoint, else fitted afresh), with
// progress and the summary on stderr (unless --quiet); returns the exit code.
int run_fit_command_line(FitCommandLine& command);
// The list's inputs with their outputs (the output directory created); empty without a list.
std::vector<stampede::app::ListedInput> listed_inputs(const FitCommandLine& command);
// Runs the list's input so (the MPI driver's ranks take whole files).
int run_listed_input(const FitCommandLine& command, const stampede::app::ListedInput& input);
