// `stampede metrics`: shear biases m, c and the GREAT08 Q from fit catalogues and truth files.
#pragma once

int run_metrics_command(int argc, char** argv);
