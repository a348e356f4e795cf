// stampede.Options: a run configuration with the ini file's keys, validated on construction.
#pragma once

#include <pybind11/pybind11.h>

#include "app/run_config.hpp"

namespace stampede::python {

void bind_options(pybind11::module_& m);

// `obj` (None, an Options, or a dict of key: value) as a validated configuration.
app::RunConfig config_from(pybind11::handle obj);

}  // namespace stampede::python
