// `stampede fit`: fits every object of a stamp grid or an image + catalogue and writes one row
// per object to a FITS table, with crash-safe resume. The command parses its arguments and
// prints; the run itself is app::FitRun.
#pragma once

int run_fit_command(int argc, char** argv);
