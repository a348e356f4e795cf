// The _stampede extension module: each part binds itself (errors first, so the others' errors
// translate).
#include <pybind11/pybind11.h>

#include "app/version.hpp"
#include "errors.hpp"
#include "options.hpp"

namespace py = pybind11;

namespace stampede::python {
void bind_fit(py::module_& m);
void bind_run(py::module_& m);
void bind_sim(py::module_& m);
void bind_io(py::module_& m);
void bind_metadetect(py::module_& m);
}  // namespace stampede::python

PYBIND11_MODULE(_stampede, m) {
  m.doc() = "stampede: galaxy shape measurement (im3shape method) for weak lensing surveys, in C++.";
  stampede::python::bind_errors(m);
  stampede::python::bind_options(m);
  stampede::python::bind_fit(m);
  stampede::python::bind_run(m);
  stampede::python::bind_sim(m);
  stampede::python::bind_io(m);
  stampede::python::bind_metadetect(m);
  m.attr("__version__") = std::string(stampede::app::program_version());
}
