"""Shared fixtures of the Python tests: the reference data, the `stampede` command, GalSim-mini stamps."""

import os
import subprocess

import numpy as np
import pytest

import stampede

DATA = os.environ.get("STAMPEDE_DATA_DIR", os.path.join(os.path.dirname(__file__), "../../../shared/data"))
CLI = os.environ.get("STAMPEDE_CLI", "stampede")
MINI = os.path.join(DATA, "galsim-great08-mini")
# The GalSim-mini sets' PSF, given explicitly so that a Python fit and a `stampede fit` run agree on it.
MINI_PSF = {"psf_beta": 3.0, "psf_fwhm": 2.85, "psf_e1": 0.0, "psf_e2": 0.05}


def grid_stamps(image, stamp_size):
    """A grid image (GREAT08 layout) as (n, S, S) stamps in the order id = iy * nx + ix."""
    ny, nx = image.shape[0] // stamp_size, image.shape[1] // stamp_size
    return image.reshape(ny, stamp_size, nx, stamp_size).transpose(0, 2, 1, 3).reshape(-1, stamp_size, stamp_size)


def run_cli(*args):
    """Runs `stampede ARGS`, failing the test with its stderr if it fails."""
    r = subprocess.run([CLI, *args], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r


def columns_equal_bitwise(a, b, skip=("time_us",)):
    """The names of the columns (outside `skip`) whose values differ bit for bit between a and b."""
    assert a.dtype.names == b.dtype.names
    differ = []
    for name in a.dtype.names:
        if name in skip:
            continue
        x, y = np.ascontiguousarray(a[name]), np.ascontiguousarray(b[name])
        if x.tobytes() != y.tobytes():
            differ.append(name)
    return differ


@pytest.fixture(scope="session")
def nf_set0():
    return stampede.read_image(os.path.join(MINI, "nf", "set_0.fits"))
