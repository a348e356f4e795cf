"""The reference metadetect package's layout read back from a file `stampede metadetect
--package-output` wrote: one structured array per shear type, as the package's do_metadetect
returns them ({"noshear": ..., "1p": ..., "1m": ..., "2p": ..., "2m": ...}), with its column
names and shapes (integers as int64, reals as float64: the values the file holds), so analysis code
written for the package reads it unchanged.
"""

import numpy as np

from ._stampede import fits_hdus, read_table

SHEAR_TYPES = ("noshear", "1p", "1m", "2p", "2m")


def _field(name, values):
    """The numpy dtype entry for a column as read_table returned it."""
    if values.dtype.kind == "U":
        return (name, "U6")
    return (name, values.dtype.str, values.shape[1:]) if values.ndim > 1 else (name, values.dtype.str)


def read_package_layout(path):
    """{shear type: structured array} of the package-layout file at `path`. A file without the
    five tables is a ValueError naming it and the missing HDU."""
    hdus = {h["name"]: h for h in fits_hdus(path) if h["name"]}
    out = {}
    for shear_type in SHEAR_TYPES:
        if shear_type not in hdus:
            raise ValueError(f"{path}: no HDU '{shear_type}' (a `stampede metadetect --package-output` file has "
                             f"one per shear type: {', '.join(SHEAR_TYPES)})")
        columns = hdus[shear_type]["columns"]
        data = read_table(path, shear_type, columns)
        n = len(next(iter(data.values()))) if data else 0
        table = np.zeros(n, dtype=[_field(name, data[name]) for name in columns])
        for name in columns:
            table[name] = data[name]
        out[shear_type] = table
    return out
