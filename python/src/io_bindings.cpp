// stampede.read_image and read_results: FITS input and result tables as numpy, for users without
// astropy or fitsio (and for comparing a Python fit with a `stampede fit` table).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <string>
#include <vector>

#include "io/catalog_reader.hpp"
#include "io/fits_file.hpp"
#include "arguments.hpp"
#include "numpy_arrays.hpp"

namespace py = pybind11;

namespace stampede::python {

void bind_io(py::module_& m) {
  m.def(
      "read_image",
      [](py::args args, py::kwargs kwargs) {
        const std::string path = Arguments("read_image", args, kwargs, {{"path", true}}).text("path");
        std::vector<double> pixels;
        long nx = 0, ny = 0;
        {
          py::gil_scoped_release release;
          io::FitsFile f = io::FitsFile::open_read(path);
          const auto shape = f.image_shape();
          nx = shape.nx, ny = shape.ny;
          pixels = f.read_image();
        }
        py::array_t<double> out(std::vector<py::ssize_t>{ny, nx});
        std::copy(pixels.begin(), pixels.end(), out.mutable_data());
        return out;
      },
      "read_image(path)\n\nThe first image of a FITS file (CFITSIO syntax: 'f.fits[2]', 'f.fits.gz'), as a 2-D float64 array "
      "[y, x].");
  m.def(
      "read_results",
      [](py::args args, py::kwargs kwargs) {
        const std::string path = Arguments("read_results", args, kwargs, {{"path", true}}).text("path");
        std::vector<ObjectRecord> rows;
        io::PositionColumns positions;
        bool metacal = false;
        {
          py::gil_scoped_release release;
          io::CatalogReader r = io::CatalogReader::open(path);
          positions = r.positions();
          metacal = r.metacal();
          rows = r.records(0, r.rows());
        }
        return result_array(rows, positions, metacal);
      },
      "read_results(path)\n\nThe RESULTS table of a `stampede fit` output as a structured array of its schema columns (the dtype "
      "fit_stamps returns for grid input).");
}

}  // namespace stampede::python
