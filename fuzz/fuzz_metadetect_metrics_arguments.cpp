// Fuzz target: the `stampede metrics --metadetect` command line (tools/metadetect_metrics_command)
// over fixed tables: a shear pair and its turned pair of two cells, a pgauss table, a copy, an
// unfinished partial, a text file (made once, in FIXED below; fuzz/metadetect_metrics.dict names
// them). The input is the argument vector, arguments separated by NUL bytes. --json is dropped (it
// writes a file the input names). A command the tool accepts prints figures; every refusal is a
// std::invalid_argument or a stampede::Error naming what is wrong: anything else is a finding.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/cell_simulation.hpp"
#include "app/metadetect_run.hpp"
#include "engine/sim/cell_sim.hpp"
#include "tools/metadetect_metrics_command.hpp"

namespace {

constexpr const char* kFixed = "/tmp/stampede-fuzz-metadetect-metrics";

void make_tables() {
  namespace fs = std::filesystem;
  if (fs::exists(std::string(kFixed) + "/done")) return;
  fs::create_directories(kFixed);
  const std::string dir = kFixed;
  stampede::CellSimOptions so;
  so.snr = 1e4;
  so.grid = 3;
  stampede::app::CellOutputOptions out;
  out.cells = 2, out.pair = true, out.overwrite = true;
  stampede::app::write_cell_simulation(so, out, dir + "/sims");
  so.rotate = true;
  stampede::app::write_cell_simulation(so, out, dir + "/turned");
  auto run = [&](const std::string& sub, const std::string& name, bool pgauss) {
    stampede::app::MetadetectRunOptions o;
    for (int k = 0; k < 2; ++k) o.inputs.push_back(dir + "/" + sub + "/cell_000" + std::to_string(k) + ".fits");
    o.output = dir + "/" + name;
    o.threads = 1;
    o.overwrite = true;
    if (pgauss) o.metadetect.measurement = stampede::MetadetectMeasurement::kPgauss;
    stampede::app::run_metadetect(o);
  };
  run("sims", "plus.fits", false);
  run("sims/minus", "minus.fits", false);
  run("turned", "turned.fits", false);
  run("turned/minus", "turned_minus.fits", false);
  run("sims", "pgauss.fits", true);
  fs::copy_file(dir + "/plus.fits", dir + "/copy.fits", fs::copy_options::overwrite_existing);
  fs::copy_file(dir + "/plus.fits", dir + "/plus.fits.partial", fs::copy_options::overwrite_existing);
  std::ofstream(dir + "/text.fits") << "not a table\n";
  std::ofstream(dir + "/done") << "";
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  make_tables();
  std::freopen("/dev/null", "w", stdout);  // the figures; refusals are thrown, not printed
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> args{"metrics"};
  for (std::size_t begin = 0; begin <= bytes.size();) {
    const std::size_t end = std::min(bytes.find('\0', begin), bytes.size());
    std::string arg = bytes.substr(begin, end - begin);
    if (arg == "--json") arg = "--seed";
    args.push_back(std::move(arg));
    begin = end + 1;
  }
  if (args.size() > 32) args.resize(32);
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  try {
    run_metadetect_metrics_command(static_cast<int>(args.size()), argv.data());
  } catch (const std::invalid_argument&) {
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError, CatalogError, FileError) naming the file
  }
  return 0;
}
