// stampede.run_fit: the `stampede fit` run over files (app::FitRun), from Python.
#include <pybind11/functional.h>
#include <pybind11/stl.h>
#include <pybind11/pybind11.h>

#include <exception>
#include <string>

#include "app/fit_run.hpp"
#include "app/shard_merge.hpp"
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

}  // namespace

void bind_run(py::module_& m) {
  m.def(
      "run_fit",
      [](const std::string& input, const std::string& output, const std::string& catalog, const std::string& weight,
         const std::string& text_output, py::handle options, int threads, bool resume, bool overwrite,
         py::object progress, py::object shard, const std::string& meds) {
        app::FitRunOptions a;
        a.input = input;
        a.meds = meds;
        a.output = output;
        a.catalog = catalog;
        a.weight = weight;
        a.text_output = text_output;
        a.config = config_from(options);
        a.threads = threads;
        a.resume = resume;
        a.overwrite = overwrite;
        if (!shard.is_none()) {
          const auto pair = shard.cast<std::pair<int, int>>();  // (i, N)
          a.shard = pair.first;
          a.shards = pair.second;
        }
        // The callbacks run on the pipeline's writer thread: they take the GIL, and a Python
        // exception in one is kept and raised when the run has ended (the run itself goes on).
        std::exception_ptr callback_error;
        if (!progress.is_none()) {
          a.on_progress = [&](const app::FitRunProgress& p) {
            py::gil_scoped_acquire gil;
            if (callback_error) return;
            try {
              progress(p.objects_done, p.objects_total, p.seconds);
            } catch (py::error_already_set&) {
              callback_error = std::current_exception();
            }
          };
          a.progress_interval = 1.0;
        }
        a.on_warning = [&](const std::string& text) {
          py::gil_scoped_acquire gil;
          if (PyErr_WarnEx(PyExc_UserWarning, text.c_str(), 1) != 0 && !callback_error) {
            callback_error = std::make_exception_ptr(py::error_already_set());
          }
        };
        app::RunSummary s;
        {
          py::gil_scoped_release release;
          s = app::FitRun(a).run();
        }
        if (callback_error) std::rethrow_exception(callback_error);
        return summary_dict(s);
      },
      py::arg("input") = "", py::arg("output") = "", py::arg("catalog") = "", py::arg("weight") = "",
      py::arg("text_output") = "", py::arg("options") = py::none(), py::arg("threads") = 0, py::arg("resume") = false,
      py::arg("overwrite") = false, py::arg("progress") = py::none(), py::arg("shard") = py::none(),
      py::arg("meds") = "", R"doc(
Runs `stampede fit` over files: `input` a grid of stamps (or, with `catalog`, the image to cut
them from), or `meds` a MEDS tile instead (each object fitted on its cutouts, as `stampede fit
--meds`; options meds_*), `output` the FITS table ("" = none), `weight` an inverse-variance image. `options` as
for Options; `progress(done, total, seconds)` is called about once a second. Warnings (e.g. an
input that records another PSF) arrive as UserWarning. `shard=(i, N)` fits shard i of N, as
`stampede fit --shard i/N` (join them with merge_shards). Returns the run summary as a dict
(objects, status counts, phase times, objects_per_second, report).
)doc");

  m.def(
      "merge_shards",
      [](const std::vector<std::string>& shards, const std::string& output, bool overwrite) {
        app::ShardMergeOptions o;
        o.shards = shards;
        o.output = output;
        o.overwrite = overwrite;
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
      py::arg("shards"), py::arg("output"), py::arg("overwrite") = false,
      "Joins the tables of run_fit(shard=(i, N)) or `stampede fit --shard` runs into the single run's table, as "
      "`stampede merge`.");
}

}  // namespace stampede::python
