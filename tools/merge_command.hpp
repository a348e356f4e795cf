// `stampede merge`: the tables of a job array's `stampede fit --shard I/N` runs joined into one.
#pragma once

int run_merge_command(int argc, char** argv);
