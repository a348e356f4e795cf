// The module's exception classes and the translation of the C++ error types into them.
#pragma once

#include <pybind11/pybind11.h>

namespace stampede::python {

// stampede.Error (a RuntimeError) and its subclasses: ConfigError (also a ValueError: a bad option
// is a bad argument), FitsError, CatalogError and FileError (also OSError: the file system said
// no); registers a translator so that every stampede::Error raised under a binding arrives as one of
// them, std::invalid_argument as ValueError, and nothing aborts the interpreter.
void bind_errors(pybind11::module_& m);

// The stampede.ConfigError class, for bindings that reject an argument themselves.
pybind11::handle config_error();

}  // namespace stampede::python
