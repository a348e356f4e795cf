// stampede.Fitter, fit_stamp and fit_stamps: fits of numpy arrays through app/array_fit.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <climits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "app/array_fit.hpp"
#include "app/fit_run.hpp"
#include "engine/common/quoted_value.hpp"
#include "arguments.hpp"
#include "numpy_arrays.hpp"
#include "options.hpp"

namespace py = pybind11;

namespace stampede::python {

namespace {

// A PSF sample image (2-D array) as a model, copied (the caller may change the array later).
PsfModel psf_from_array(const DoubleArray& a, py::ssize_t k, int oversampling, bool pixel_integrated) {
  auto img = std::make_shared<PsfImage>();
  const py::ssize_t ny = a.shape(a.ndim() - 2), nx = a.shape(a.ndim() - 1);
  img->nx = static_cast<int>(nx);
  img->ny = static_cast<int>(ny);
  const double* p = a.data() + k * nx * ny;
  img->pixels.assign(p, p + nx * ny);
  img->oversampling = oversampling;
  img->pixel_integrated = pixel_integrated;
  return PsfModel::Image(std::move(img));
}

// psf (None, a 2-D array for every stamp, or a 3-D array of one per stamp) as models; checks that
// each covers no more than the stamp.
std::vector<PsfModel> psfs_from(py::handle psf, py::ssize_t count, int stamp_size, int oversampling,
                                bool pixel_integrated) {
  std::vector<PsfModel> out;
  if (psf.is_none()) return out;
  if (oversampling < 1) throw py::value_error("psf_oversampling = " + std::to_string(oversampling) + ": must be >= 1");
  const DoubleArray a = as_float64(psf, {2, 3}, "psf");
  const py::ssize_t ny = a.shape(a.ndim() - 2), nx = a.shape(a.ndim() - 1);
  if (std::max(nx, ny) > static_cast<py::ssize_t>(stamp_size) * oversampling)
    throw py::value_error("psf is " + std::to_string(ny) + " x " + std::to_string(nx) + " samples at psf_oversampling " +
                          std::to_string(oversampling) + ", larger than the " + std::to_string(stamp_size) +
                          "-pixel stamp: cut it to at most " + std::to_string(stamp_size * oversampling) +
                          " samples per side");
  if (a.ndim() == 3 && a.shape(0) != count)
    throw py::value_error("psf holds " + std::to_string(a.shape(0)) + " PSFs for " + std::to_string(count) +
                          " stamps (give one 2-D PSF, or one per stamp)");
  const py::ssize_t n = a.ndim() == 2 ? 1 : a.shape(0);
  for (py::ssize_t k = 0; k < n; ++k) out.push_back(psf_from_array(a, k, oversampling, pixel_integrated));
  return out;
}

// The weights argument checked against the stamps' shape.
std::optional<DoubleArray> weights_from(py::handle weights, const DoubleArray& stamps) {
  if (weights.is_none()) return std::nullopt;
  DoubleArray w = as_float64(weights, {static_cast<int>(stamps.ndim())}, "weights");
  for (py::ssize_t d = 0; d < stamps.ndim(); ++d)
    if (w.shape(d) != stamps.shape(d))
      throw py::value_error("weights have shape " + py::str(py::tuple(w.attr("shape"))).cast<std::string>() +
                            ", the stamps " + py::str(py::tuple(stamps.attr("shape"))).cast<std::string>());
  return w;
}

int square_side(const DoubleArray& a, const char* what) {
  const py::ssize_t ny = a.shape(a.ndim() - 2), nx = a.shape(a.ndim() - 1);
  if (nx != ny)
    throw py::value_error(std::string(what) + " must be square, not " + std::to_string(ny) + " x " + std::to_string(nx));
  return static_cast<int>(nx);
}

// A PSF or a noise level given two ways is refused, as the command line refuses --weight with
// noise_sigma != 0 and psf_image with another psf_input.
void check_psf_given_once(const app::RunConfig& cfg, const std::string& where) {
  const auto set = cfg.explicitly_set.find("psf_input");
  if (set != cfg.explicitly_set.end() && cfg.psf_kind != PsfKind::kImage)
    throw io::ConfigError(where + " (an image) and option 'psf_input' = " + app::get_option(cfg, "psf_input") +
                          " both give the PSF; give one (leave psf_input out, or psf=None)");
  if (!cfg.psf_image.empty())
    throw io::ConfigError(where + " (an image) and option 'psf_image' = " +
                          quoted_value(cfg.psf_image, kQuotedPathMaxBytes) + " both give the PSF; give one");
}

void check_noise_given_once(const app::RunConfig& cfg, const std::string& where) {
  if (cfg.fitter.noise_sigma != 0)
    throw io::ConfigError("option 'noise_sigma' = " + app::get_option(cfg, "noise_sigma") + " and " + where +
                          " both give the noise; give one (noise_sigma = 0 with weights)");
}

// The Python-side Fitter: a SingleStampFitter behind a mutex, so that Python threads may share one
// (each call releases the GIL while it fits).
class PyFitter {
 public:
  PyFitter(py::handle options, long long stamp_size, py::handle psf, long long psf_oversampling,
           bool psf_pixel_integrated, const std::string& function) {
    if (stamp_size < 1 || stamp_size > 100000)
      throw py::value_error(function + "(): stamp_size = " + std::to_string(stamp_size) + ": must be in [1, 100000]");
    if (psf_oversampling < 1 || psf_oversampling > 1000)
      throw py::value_error(function + "(): psf_oversampling = " + std::to_string(psf_oversampling) +
                            ": must be in [1, 1000]");
    const app::RunConfig cfg = config_from(options);
    if (!psf.is_none()) check_psf_given_once(cfg, function + "(): psf");
    std::vector<PsfModel> psfs = psfs_from(psf, 1, static_cast<int>(stamp_size), static_cast<int>(psf_oversampling),
                                           psf_pixel_integrated);
    if (psfs.size() > 1) throw py::value_error(function + "(): psf: a Fitter takes one 2-D PSF, not one per stamp");
    std::optional<PsfModel> model;
    if (!psfs.empty()) model = psfs.front();
    config_ = cfg;
    py::gil_scoped_release release;
    fitter_ = std::make_unique<app::SingleStampFitter>(cfg, static_cast<int>(stamp_size), model);
    metacal_ = cfg.metacal.enabled;
  }

  int stamp_size() const { return fitter_->stamp_size(); }

  py::dict fit(py::handle stamp, py::handle weights, std::int64_t id, const std::string& function) {
    const DoubleArray s = as_float64(stamp, {2}, "stamp");
    if (square_side(s, "stamp") != fitter_->stamp_size())
      throw py::value_error("stamp is " + std::to_string(s.shape(0)) + " x " + std::to_string(s.shape(1)) +
                            ", this Fitter's stamps " + std::to_string(fitter_->stamp_size()) + " x " +
                            std::to_string(fitter_->stamp_size()));
    if (!weights.is_none()) check_noise_given_once(config_, function + "(): weight");
    const std::optional<DoubleArray> w = weights_from(weights, s);
    ObjectRecord row;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      row = fitter_->fit(values(s), w ? values(*w) : std::span<const double>(), id);
    }
    return result_dict(row, io::PositionColumns::kGrid, metacal_);
  }

 private:
  std::unique_ptr<app::SingleStampFitter> fitter_;
  app::RunConfig config_;
  bool metacal_ = false;
  std::mutex mutex_;
};

py::array fit_stamps(py::args args, py::kwargs kwargs) {
  const Arguments a("fit_stamps", args, kwargs,
                    {{"stamps", true}, {"weights"}, {"psf"}, {"psf_oversampling"}, {"psf_pixel_integrated"},
                     {"options"}, {"threads"}, {"grid_nx"}, {"first_id"}});
  const DoubleArray s = as_float64(a.object("stamps"), {3}, "stamps");
  const int side = square_side(s, "stamps");
  const py::object weights = a.object("weights"), psf = a.object("psf"), options = a.object("options");
  const std::optional<DoubleArray> w = weights_from(weights, s);
  const long long psf_oversampling = a.integer_in("psf_oversampling", 1, 1, 1000);
  const bool psf_pixel_integrated = a.flag("psf_pixel_integrated", true);
  const long long threads = a.integer("threads", 0);
  app::check_threads(threads, a.where("threads"));
  const int grid_nx = static_cast<int>(a.integer_in("grid_nx", 0, 0, INT_MAX));
  const std::int64_t first_id = a.integer("first_id", 0);
  const app::RunConfig cfg = config_from(options);
  if (!psf.is_none()) check_psf_given_once(cfg, "fit_stamps(): psf");
  if (w) check_noise_given_once(cfg, "fit_stamps(): weights");
  app::ArrayStamps in;
  in.count = static_cast<int>(s.shape(0));
  in.stamp_size = side;
  in.pixels = values(s);
  if (w) in.weights = values(*w);
  in.psfs = psfs_from(psf, s.shape(0), side, static_cast<int>(psf_oversampling), psf_pixel_integrated);
  in.grid_nx = grid_nx;
  in.first_id = first_id;
  std::vector<ObjectRecord> rows;
  {
    py::gil_scoped_release release;
    rows = app::fit_array_stamps(cfg, in, static_cast<int>(threads));
  }
  return result_array(rows, io::PositionColumns::kGrid, cfg.metacal.enabled);
}

}  // namespace

void bind_fit(py::module_& m) {
  py::class_<PyFitter>(m, "Fitter", R"doc(
Fits stamps one at a time with a PSF prepared once: the cheap per-stamp call.

    fitter = stampede.Fitter(options, stamp_size=39)            # the options' PSF
    fitter = stampede.Fitter(options, stamp_size=39, psf=img)   # a PSF image (2-D array)
    row = fitter.fit(stamp, weight=None)                        # dict of the FITS table's columns

`options`: a stampede.Options, a dict of option: value, or None (defaults). `psf_oversampling`:
PSF samples per data pixel; `psf_pixel_integrated`: whether they are pixel integrals (GalSim's
drawImage default) or point samples (method='no_pixel'). Weights are inverse variances (0 masks a
pixel); without them the fit uses noise_sigma. Bad pixels (NaN, Inf, negative weights) give a row
with status bad_pixels, not an exception.
)doc")
      .def(py::init([](py::args args, py::kwargs kwargs) {
             const Arguments a("Fitter", args, kwargs,
                               {{"options"}, {"stamp_size"}, {"psf"}, {"psf_oversampling"}, {"psf_pixel_integrated"}});
             return std::make_unique<PyFitter>(a.object("options"), a.integer("stamp_size", 39), a.object("psf"),
                                               a.integer("psf_oversampling", 1), a.flag("psf_pixel_integrated", true),
                                               "Fitter");
           }),
           "Fitter(options=None, stamp_size=39, psf=None, psf_oversampling=1, psf_pixel_integrated=True)")
      .def_property_readonly("stamp_size", &PyFitter::stamp_size)
      .def(
          "fit",
          [](PyFitter& f, py::args args, py::kwargs kwargs) {
            const Arguments a("Fitter.fit", args, kwargs, {{"stamp", true}, {"weight"}, {"id"}});
            return f.fit(a.object("stamp"), a.object("weight"), a.integer("id", 0), "Fitter.fit");
          },
          "fit(stamp, weight=None, id=0)\n\nFits one square 2-D stamp; returns {column: value} as one row of the FITS "
          "table.");

  m.def(
      "fit_stamp",
      [](py::args args, py::kwargs kwargs) {
        const Arguments a("fit_stamp", args, kwargs,
                          {{"stamp", true}, {"weight"}, {"psf"}, {"psf_oversampling"}, {"psf_pixel_integrated"},
                           {"options"}});
        const DoubleArray s = as_float64(a.object("stamp"), {2}, "stamp");
        PyFitter f(a.object("options"), square_side(s, "stamp"), a.object("psf"), a.integer("psf_oversampling", 1),
                   a.flag("psf_pixel_integrated", true), "fit_stamp");
        return f.fit(s, a.object("weight"), 0, "fit_stamp");
      },
      "fit_stamp(stamp, weight=None, psf=None, psf_oversampling=1, psf_pixel_integrated=True, options=None)\n\n"
      "Fits one stamp (a Fitter made for the call: for many stamps make one Fitter, or use fit_stamps).");

  py::list names;
  for (int i = 0; i < kFitStatusCount; ++i) names.append(ToString(static_cast<FitStatus>(i)));
  m.attr("fit_status_names") = names;  // the `status` column's codes, by value

  m.def("fit_stamps", &fit_stamps, R"doc(fit_stamps(stamps, weights=None, psf=None, psf_oversampling=1,
           psf_pixel_integrated=True, options=None, threads=0, grid_nx=0, first_id=0)

Fits a batch of stamps (N x S x S) on the engine's threads, the GIL released, and returns a numpy
structured array with exactly the columns of `stampede fit`'s RESULTS table (grid positions: id,
ix, iy; then x0 ... psf_fwhm). Rows are numbered as a grid read row by row: id = first_id + k,
ix = k % grid_nx, iy = k // grid_nx (grid_nx 0: one row). `psf`: None (the options' PSF), one
2-D PSF image, or N of them (N x P x P); not with options that give the PSF (psf_input,
psf_image). `weights` (inverse variances): not with noise_sigma != 0. `threads` 0: all cores. The rows equal `stampede fit`'s on
the same stamps and options, bit for bit, whatever the thread count.
)doc");
}

}  // namespace stampede::python
