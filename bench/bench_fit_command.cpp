// End to end (docs/performance.md): `stampede fit` as a user runs it, the whole process per
// iteration (start-up, reading, fitting, writing the table), over 10,000 GREAT08-like stamps at
// S/N 20 (`stampede sim great08 --grid 100 --snr 20 --seed 2020`, the surrogate experiment's set,
// simulated once into STAMPEDE_BENCH_DIR, default $TMPDIR/stampede_bench_fit_command, and reused):
//   BM_StampedeFitS20/threads:N   objects/s of the default fit on N threads (items = objects)
//   BM_StampedeMetacalWmomS20     metacal = true, metacal_model = wmom on one thread (its budget:
//                                 <= 5 ms a row, the whole process; docs/metacal.md)
// The speed-up is threads:2 / threads:1 from one run (bench/run interleaves the repetitions).
#include <benchmark/benchmark.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace {

namespace fs = std::filesystem;

constexpr int kObjects = 10000;

std::string quoted(const std::string& s) { return "'" + s + "'"; }

// The stamps, simulated on first use; "" (with the error set on `state`) if that failed.
std::string grid(benchmark::State& state) {
  const char* env = std::getenv("STAMPEDE_BENCH_DIR");
  const fs::path dir = env ? fs::path(env) : fs::temp_directory_path() / "stampede_bench_fit_command";
  const fs::path set = dir / "sim" / "set_0.fits";
  if (!fs::exists(set)) {
    const std::string cmd = quoted(STAMPEDE_BINARY) + " sim great08 --out " + quoted((dir / "sim").string()) +
                            " --sets 1 --grid 100 --snr 20 --seed 2020 --overwrite > /dev/null";  // all cores
    if (std::system(cmd.c_str()) != 0 || !fs::exists(set)) {
      state.SkipWithError("could not simulate the stamps");
      return "";
    }
  }
  return set.string();
}

void run_fit(benchmark::State& state, const std::string& name, const std::string& options) {
  const std::string in = grid(state);
  if (in.empty()) return;
  const std::string out = (fs::path(in).parent_path() / (name + "_" + std::to_string(state.range(0)) + ".fits")).string();
  const std::string cmd = quoted(STAMPEDE_BINARY) + " fit " + quoted(in) + " -o " + quoted(out) +
                          " --overwrite --quiet --set noise_sigma=1 " + options + " --threads " + std::to_string(state.range(0));
  for (auto _ : state) {
    const int status = std::system(cmd.c_str());
    if (status == -1 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      state.SkipWithError("stampede fit failed");
      return;
    }
  }
  state.SetItemsProcessed(state.iterations() * kObjects);
}

void BM_StampedeFitS20(benchmark::State& state) { run_fit(state, "fit", ""); }
void BM_StampedeMetacalWmomS20(benchmark::State& state) {
  run_fit(state, "metacal_wmom", "--set metacal=true --set metacal_model=wmom");
}
BENCHMARK(BM_StampedeFitS20)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);
BENCHMARK(BM_StampedeMetacalWmomS20)->ArgName("threads")->Arg(1)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
