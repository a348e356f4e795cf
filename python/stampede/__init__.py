"""stampede: galaxy shape measurement (the im3shape method) for weak lensing surveys, in C++.

Fit numpy arrays (GalSim's Image.array works as it is), run the engine over files, simulate
GREAT08-like sets and measure shear biases:

    import stampede
    sim = stampede.simulate_great08(noise_free=True, grid=4)
    rows = stampede.fit_stamps(sim["stamps"], options={"psf_e2": 0.05, "renderer": "exact"})
    print(rows["e1"] - sim["truth"]["e1_obs"])

Every error is a stampede.Error (bad arguments: ValueError; a bad option: stampede.ConfigError,
which is both).
"""

from ._stampede import (  # noqa: F401
    CatalogError,
    ConfigError,
    Error,
    FileError,
    FitsError,
    Fitter,
    Options,
    __version__,
    detect,
    fit_stamp,
    fit_stamps,
    fit_status_names,
    fits_hdus,
    fits_header,
    merge_shards,
    metacal_set_shear,
    metadetect,
    metadetect_metrics,
    option_help,
    read_image,
    read_results,
    read_table,
    run_fit,
    set_shear,
    shear_excluding_flags,
    shear_metrics,
    simulate_great08,
)
from .package_layout import read_package_layout  # noqa: F401

__all__ = [
    "CatalogError", "ConfigError", "Error", "FileError", "FitsError", "Fitter", "Options", "detect",
    "fit_stamp", "fit_stamps", "fit_status_names", "fits_hdus", "fits_header", "merge_shards", "metacal_set_shear", "metadetect", "metadetect_metrics", "option_help", "read_image", "read_package_layout", "read_results", "read_table", "run_fit", "set_shear", "shear_excluding_flags", "shear_metrics",
    "simulate_great08",
]
