// The module's exceptions; see errors.hpp.
#include "errors.hpp"

#include <exception>
#include <stdexcept>

#include "engine/common/error.hpp"
#include "io/catalog_writer.hpp"
#include "io/durable_file.hpp"
#include "io/fits_error.hpp"
#include "app/run_config.hpp"

namespace py = pybind11;

namespace stampede::python {

namespace {

// Classes live for the interpreter's life: the module holds a reference to each.
PyObject* g_error = nullptr;
PyObject* g_config_error = nullptr;
PyObject* g_fits_error = nullptr;
PyObject* g_catalog_error = nullptr;
PyObject* g_file_error = nullptr;

PyObject* new_class(py::module_& m, const char* name, py::tuple bases, const char* doc) {
  const std::string qualified = std::string("stampede.") + name;
  PyObject* cls = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases.ptr(), nullptr);
  if (cls == nullptr) throw py::error_already_set();
  m.add_object(name, py::handle(cls));  // the module's reference; ours is the one returned
  return cls;
}

}  // namespace

py::handle config_error() { return g_config_error; }

void bind_errors(py::module_& m) {
  g_error = new_class(m, "Error", py::make_tuple(py::handle(PyExc_RuntimeError)),
                      "Base class of every error stampede raises (bad arguments aside: ValueError).");
  const py::handle base(g_error);
  g_config_error = new_class(m, "ConfigError", py::make_tuple(base, py::handle(PyExc_ValueError)),
                             "An option that is unknown, does not parse or breaks a constraint; the message "
                             "names the key, the value and the rule.");
  g_fits_error = new_class(m, "FitsError", py::make_tuple(base),
                           "A FITS file that cannot be read or written; the message names the file, HDU and "
                           "keyword or column.");
  g_catalog_error = new_class(m, "CatalogError", py::make_tuple(base),
                              "A catalogue (input or output table) that is inconsistent or cannot be written.");
  g_file_error = new_class(m, "FileError", py::make_tuple(base, py::handle(PyExc_OSError)),
                           "A file-system operation that failed (create, rename, lock).");

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const py::builtin_exception&) {
      throw;  // pybind11's own (TypeError, ValueError, ...): its default translator
    } catch (const io::ConfigError& e) {
      PyErr_SetString(g_config_error, e.what());
    } catch (const io::FitsError& e) {
      PyErr_SetString(g_fits_error, e.what());
    } catch (const io::CatalogError& e) {
      PyErr_SetString(g_catalog_error, e.what());
    } catch (const io::FileError& e) {
      PyErr_SetString(g_file_error, e.what());
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const std::bad_alloc&) {
      throw;  // MemoryError
    } catch (const std::exception& e) {
      PyErr_SetString(g_error, e.what());  // stampede::Error and any other runtime failure
    }
  });
}

}  // namespace stampede::python
