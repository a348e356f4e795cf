// stampede.run_fit: the `stampede fit` run over files (app::FitRun), from Python.
#include <pybind11/functional.h>
#include <pybind11/stl.h>
#include <pybind11/pybind11.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "app/fit_run.hpp"
#include "app/shard_merge.hpp"
#include "io/result_columns.hpp"
#include "arguments.hpp"
#include "options.hpp"

namespace py = pybind11;

namespace stampede::python {

namespace {

py::dict summary_dict(const app::RunSummary& s) {
  py::dict statuses;
  for (int i = 0; i < kFitStatusCount; ++i)
    if (s.by_status[i] > 0) statuses[ToString(static_cast<FitStatus>(i))] = s.by_status[i];
  py::dict out;
  out["objects"] = s.objects;
  out["resumed"] = s.resumed;
  out["skipped"] = s.skipped;
  out["batches"] = s.batches;
  out["threads"] = s.threads;
  out["status"] = statuses;
  out["setup_seconds"] = s.setup_seconds;
  out["pipeline_seconds"] = s.pipeline_seconds;
  out["finish_seconds"] = s.finish_seconds;
  out["total_seconds"] = s.total_seconds;
  out["objects_per_second"] = s.objects_per_second();
  out["input"] = s.input;
  out["catalog"] = s.catalog;
  out["weight"] = s.weight;
  out["output"] = s.output;
  out["text_output"] = s.text_output;
  out["report"] = s.BriefReport();
  return out;
}

// run_fit's run goes on a thread of its own while the calling thread, holding the GIL only
// briefly, delivers the progress calls and warnings and checks for signals: so Ctrl-C (and an
// exception from `progress` or from a warning made an error) stops the run as the CLI's SIGINT
// does, its partial outputs kept for resume, and the exception is raised once the run has stopped.
py::dict run_watched(app::FitRunOptions a, py::object progress) {
  struct Shared {
    std::mutex mutex;
    std::condition_variable changed;
    bool done = false;
    std::optional<app::RunProgress> progress;
    std::vector<std::string> warnings;
  } shared;
  std::atomic<bool> stop{false};
  a.stop = &stop;
  if (!progress.is_none()) {
    a.on_progress = [&](const app::RunProgress& p) {
      const std::lock_guard<std::mutex> lock(shared.mutex);
      shared.progress = p;
      shared.changed.notify_one();
    };
    a.progress_interval = 1.0;
  }
  a.on_warning = [&](const std::string& text) {
    const std::lock_guard<std::mutex> lock(shared.mutex);
    shared.warnings.push_back(text);
    shared.changed.notify_one();
  };
  app::RunSummary summary;
  std::exception_ptr run_error;
  std::thread runner([&] {
    try {
      summary = app::FitRun(a).run();
    } catch (...) {
      run_error = std::current_exception();
    }
    const std::lock_guard<std::mutex> lock(shared.mutex);
    shared.done = true;
    shared.changed.notify_one();
  });
  std::optional<py::error_already_set> python_error;
  try {
    for (bool done = false; !done;) {
      std::optional<app::RunProgress> p;
      std::vector<std::string> warnings;
      {
        py::gil_scoped_release release;
        std::unique_lock<std::mutex> lock(shared.mutex);
        shared.changed.wait_for(lock, std::chrono::milliseconds(100),
                                [&] { return shared.done || shared.progress || !shared.warnings.empty(); });
        done = shared.done;
        p.swap(shared.progress);
        warnings.swap(shared.warnings);
      }
      if (python_error) continue;  // stopping: drain until the run has ended
      for (const std::string& w : warnings)
        if (PyErr_WarnEx(PyExc_UserWarning, w.c_str(), 1) != 0) throw py::error_already_set();
      if (p) progress(p->done, p->total, p->seconds);
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    }
  } catch (py::error_already_set& e) {
    python_error.emplace(std::move(e));
    stop.store(true);
    py::gil_scoped_release release;
    runner.join();
  }
  if (runner.joinable()) {
    py::gil_scoped_release release;
    runner.join();
  }
  if (python_error) throw std::move(*python_error);
  if (run_error) std::rethrow_exception(run_error);
  return summary_dict(summary);
}

}  // namespace

void bind_run(py::module_& m) {
  m.def(
      "run_fit",
      [](py::args args, py::kwargs kwargs) {
        const Arguments in("run_fit", args, kwargs,
                           {{"input"}, {"output"}, {"catalog"}, {"weight"}, {"text_output"}, {"options"}, {"threads"},
                            {"resume"}, {"overwrite"}, {"progress"}, {"shard"}, {"meds"}, {"bands"}});
        app::FitRunOptions a;
        a.input = in.text("input");
        // One tile (a path), or one per band (a list, in the order of `bands`).
        const py::object meds = in.object("meds");
        if (py::isinstance<py::list>(meds) || py::isinstance<py::tuple>(meds)) {
          if (py::len(meds) == 0)
            throw py::value_error(in.where("meds") + " is an empty list: give a MEDS tile's path, or one tile per band");
          a.meds = in.texts("meds");
          for (std::size_t k = 0; k < a.meds.size(); ++k)
            if (a.meds[k].empty())
              throw py::value_error(in.where("meds") + "[" + std::to_string(k) + "] is an empty path: give each band's tile");
        } else if (!meds.is_none()) {
          const std::string tile = in.text("meds");
          if (!tile.empty()) a.meds = {tile};  // "" is the default: no tile
        }
        if (!in.object("bands").is_none()) a.bands = in.names("bands");
        // Here as well as in the run, so that the error names run_fit's argument.
        if (std::string why; !io::are_band_names(a.bands, &why)) throw py::value_error(in.where("bands") + ": " + why);
        if (!a.bands.empty() && a.meds.empty())
          throw py::value_error(in.where("bands") + " names the bands of the meds tiles: give meds");
        a.output = in.text("output");
        a.catalog = in.text("catalog");
        a.weight = in.text("weight");
        a.text_output = in.text("text_output");
        a.config = config_from(in.object("options"));
        const long long threads = in.integer("threads", 0);
        app::check_threads(threads, in.where("threads"));
        a.threads = static_cast<int>(threads);
        a.resume = in.flag("resume", false);
        a.overwrite = in.flag("overwrite", false);
        const py::object progress = in.object("progress");
        if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
          throw py::type_error(in.where("progress") + " must be callable as progress(done, total, seconds), not " +
                               describe(progress));
        if (in.given("shard")) {
          const py::object shard = in.object("shard");
          const auto n = py::isinstance<py::tuple>(shard) || py::isinstance<py::list>(shard) ? py::len(shard) : 0;
          if (n != 2)
            throw py::type_error(in.where("shard") + " must be a pair (i, N) of ints, not " + describe(shard));
          const py::args pair = py::reinterpret_borrow<py::args>(py::tuple(shard));
          const Arguments ij(in.where("shard"), pair, py::kwargs(), {{"i"}, {"N"}});
          a.shard = static_cast<int>(ij.integer_in("i", 0, 0, 999999));
          a.shards = static_cast<int>(ij.integer_in("N", 1, 1, 1000000));
          if (a.shard >= a.shards)
            throw py::value_error(in.where("shard") + " = (" + std::to_string(a.shard) + ", " +
                                  std::to_string(a.shards) + "): must have 0 <= i < N");
        }
        return run_watched(std::move(a), progress);
      },
      R"doc(run_fit(input="", output="", catalog="", weight="", text_output="", options=None, threads=0,
        resume=False, overwrite=False, progress=None, shard=None, meds="", bands=None)

Runs `stampede fit` over files: `input` a grid of stamps (or, with `catalog`, the image to cut
them from), or `meds` a MEDS tile instead (each object fitted on its cutouts, as `stampede fit
--meds`; options meds_*) or a list of tiles, one per band of the same objects, fitted jointly
(`bands` their names, default b0, b1, ...; as `stampede fit --meds ... --bands`), `output` the FITS
table ("" = none), `weight` an inverse-variance image.
Paths are str or os.PathLike. `options` as for Options; `threads` 0: all cores, else 1..4096.
`progress(done, total, seconds)` is called about once a second. Warnings (e.g. an input that
records another PSF) arrive as UserWarning. `shard=(i, N)` fits shard i of N, as `stampede fit
--shard i/N` (join them with merge_shards). Ctrl-C (or an exception raised by `progress`) stops the
run as the CLI's SIGINT does: the batches in flight are written, the output stays partial
(OUTPUT.partial and its checkpoint) and run_fit(..., resume=True) continues it; the exception is
raised once the run has stopped. With resume=True an output this run already completed is left as
it is ('skipped' True in the summary; another run's complete output is refused). Returns the run
summary as a dict (objects, status counts, phase times, objects_per_second, report, skipped).
)doc");

  m.def(
      "merge_shards",
      [](py::args args, py::kwargs kwargs) {
        const Arguments in("merge_shards", args, kwargs, {{"shards", true}, {"output", true}, {"overwrite"}});
        app::ShardMergeOptions o;
        o.shards = in.texts("shards");
        o.output = in.text("output");
        o.overwrite = in.flag("overwrite", false);
        app::ShardMergeSummary s;
        {
          py::gil_scoped_release release;
          s = app::merge_shards(o);
        }
        py::dict out;
        out["shards"] = s.shards;
        out["rows"] = s.rows;
        out["seconds"] = s.seconds;
        return out;
      },
      "merge_shards(shards, output, overwrite=False)\n\nJoins the tables of run_fit(shard=(i, N)) or `stampede fit "
      "--shard` runs (a list of paths) into the single run's table, as `stampede merge`.");
}

}  // namespace stampede::python
