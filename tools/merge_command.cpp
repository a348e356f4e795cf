// `stampede merge`; see merge_command.hpp. Argument parsing over app/shard_merge.
#include "tools/merge_command.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "app/shard_merge.hpp"
#include "tools/arguments.hpp"
#include "tools/progress_printer.hpp"

namespace {

constexpr const char* kUsage = "usage: stampede merge -o OUT.fits SHARD.fits... [--overwrite] [--quiet]\n";

void print_help() {
  std::fputs(kUsage, stdout);
  std::fputs(
      "\n"
      "Joins the tables of the N runs of `stampede fit --shard I/N` (one per job of a job array) into\n"
      "the table one `stampede fit` run writes: rows in input order, every column but time_us equal.\n"
      "The shards may be given in any order. Refused, naming the file: a table that is not a shard, a\n"
      "missing or duplicated shard, shards of another run (input, options or N differ), and a shard\n"
      "with fewer or more rows than its range (an unfinished job: resume it first). The shards of\n"
      "`stampede metadetect --shard I/N` are joined the same way (rows in cell order).\n"
      "\n"
      "  -o OUT.fits   the joined table (written as OUT.fits.partial, renamed when complete)\n"
      "  --overwrite   replace an existing OUT.fits\n"
      "  --quiet       no progress or summary on stderr\n",
      stdout);
}

}  // namespace

int run_merge_command(int argc, char** argv) {
  stampede::app::ShardMergeOptions o;
  bool quiet = false;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "--help" || s == "-h") {
      print_help();
      return 0;
    } else if (s == "-o" || s == "--output") {
      o.output = stampede::tools::option_value(argc, argv, &i);
    } else if (s == "--overwrite") {
      o.overwrite = true;
    } else if (s == "--quiet") {
      quiet = true;
    } else if (!s.empty() && s[0] == '-') {
      throw std::invalid_argument("unknown option " + stampede::tools::quoted_value(s) + " (see stampede merge --help)");
    } else {
      o.shards.push_back(s);
    }
  }
  if (o.output.empty() || o.shards.empty()) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  stampede::tools::ProgressPrinter printer(stderr, isatty(fileno(stderr)));
  const auto start = std::chrono::steady_clock::now();
  if (!quiet)
    o.on_progress = [&](long long done, long long total) {
      const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      printer.update(t, std::to_string(done) + "/" + std::to_string(total) + " rows   ");
    };
  const stampede::app::ShardMergeSummary s = stampede::app::merge_shards(o);
  printer.finish();
  if (!quiet)
    std::fprintf(stderr, "stampede merge: %d %sshards, %lld %s, %lld rows in %.1f s; wrote %s\n", s.shards,
                 s.metadetect ? "metadetect " : "", s.units, s.metadetect ? "cells" : "objects", s.rows, s.seconds,
                 o.output.c_str());
  return 0;
}
