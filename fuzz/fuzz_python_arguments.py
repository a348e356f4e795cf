#!/usr/bin/env python3
"""Fuzz target for the Python module's argument layer (docs/reliability.md).

libFuzzer cannot drive an interpreter's argument parsing, so this is a generative fuzzer: every
case calls one of the module's functions with arguments drawn from a pool of hostile values
(wrong types, numpy scalars and arrays of every dtype and layout, NaN, huge integers, NUL bytes,
paths to nothing, objects whose __index__, __float__ or __fspath__ raise, misspelt keywords, too
many positionals, random option dictionaries). Cases run in a worker process, so a crash is seen
as the worker's death, not the fuzzer's. A finding is:
  - the worker killed by a signal (a segfault, an abort) or exiting without reporting;
  - an exception other than TypeError, ValueError or stampede.Error (MemoryError, SystemError,
    OverflowError, RuntimeError from pybind11, ...);
  - an error message over 600 characters or holding an array's repr ("array(");
  - a case running past --case-timeout seconds (a hang; reported separately as "slow").
Cases are numbered and drawn from random.Random(seed * 1_000_003 + case), so any case replays alone:
    fuzz/fuzz_python_arguments.py --replay CASE [--seed S]

usage: fuzz/fuzz_python_arguments.py [--seed S] [--cases N | --cpu-seconds T] [--findings DIR]
The module comes from PYTHONPATH (build/python) and the `stampede` command from STAMPEDE_CLI.
"""

import argparse
import json
import math
import os
import pathlib
import random
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import traceback

MAX_MESSAGE = 600


# --- the pool of values --------------------------------------------------------------------------

class RaisingIndex:
    def __index__(self):
        raise ZeroDivisionError("from __index__")


class RaisingFloat:
    def __float__(self):
        raise ZeroDivisionError("from __float__")


class BytesPath:
    def __fspath__(self):
        return b"/tmp/x.fits"


class RaisingPath:
    def __fspath__(self):
        raise ZeroDivisionError("from __fspath__")


class RaisingStr:
    def __str__(self):
        raise ZeroDivisionError("from __str__")

    def __repr__(self):
        raise ZeroDivisionError("from __repr__")


def raising_callback(*args):
    raise ZeroDivisionError("from the callback")


def scalars(np):
    return [None, True, False, 0, 1, -1, 2, 3, 7, 39, 4097, 2**31, 2**63 - 1, 2**63, -2**63 - 1, 10**30,
            np.int8(3), np.uint64(2**64 - 1), np.int64(-5), np.bool_(True), 0.0, -0.0, 0.5, 2.85, 1e308, 5e-324,
            math.nan, math.inf, -math.inf, np.float32(1.5), np.float16(2), np.longdouble(2), 1 + 2j,
            "", "x", "0", "1/3", "a\0b", "\u00e9", "x" * 5000, "exact", "upsampled", "auto", "bd", b"bytes",
            (), (1,), (0, 2), (0, 1, 2), [1, 2], ("a", 3), {}, {"a": 1}, set(), object(), RaisingIndex(),
            RaisingFloat(), RaisingStr(), print, raising_callback, lambda *a: None, np.array(3.0),
            np.array([1, 2])]


def array(rng, np, ndim=None, side=None):
    ndim = rng.choice([0, 1, 2, 3, 3, 4]) if ndim is None else ndim
    side = side or rng.choice([1, 2, 5, 8, 8, 9])
    shape = [rng.choice([0, 1, 2, 3]) if d == 0 and ndim == 3 else side for d in range(ndim)]
    if rng.random() < 0.15 and ndim > 0:
        shape[-1] = side + rng.choice([-1, 1])
    dtype = rng.choice(["f8", "f8", "f8", "f4", "f2", "g", ">f8", "i4", "u1", "?", "c16", "O", "U3"])
    values = rng.choice(["zeros", "ones", "noise", "nan", "inf", "huge", "neg"])
    with np.errstate(all="ignore"):
        base = {"zeros": np.zeros(shape), "ones": np.ones(shape), "noise": np.random.default_rng(rng.randrange(99))
                .normal(size=shape), "nan": np.full(shape, np.nan), "inf": np.full(shape, np.inf),
                "huge": np.full(shape, 1e308), "neg": -np.ones(shape)}[values]
        base = np.asarray(base)  # a 0-d draw is a numpy scalar, not an array (harness finding H1)
        try:
            a = np.asarray(base.astype(dtype))
        except (TypeError, ValueError):
            a = base
    layout = rng.choice(["c", "c", "f", "strided", "readonly"])
    if layout == "f":
        a = np.asfortranarray(a)
    elif layout == "strided" and ndim > 0:
        a = np.repeat(a, 2, axis=-1)[..., ::2]
    elif layout == "readonly":
        a.setflags(write=False)
    return a


def path(rng, files):
    return rng.choice([files["grid"], pathlib.Path(files["grid"]), files["fit"], files["tile"], files["dir"],
                       files["dir"] + "/out.fits", files["dir"] + "/out.fits", "/nonexistent/x.fits", "", "/dev/null",
                       "/dev/zero", files["grid"] + "[1]", files["grid"] + "[9]", BytesPath(), RaisingPath(), 3,
                       "a\0b", files["grid"] + ".gz"])


def options(rng, np, keys):
    if rng.random() < 0.15:
        return rng.choice([None, 3, "renderer=exact", ["renderer"], {1: 2}])
    out = {"renderer": "upsampled", "upsampling": 1, "minimizer_max_iterations": 4, "padding": 0}
    for _ in range(rng.choice([0, 0, 1, 1, 2])):
        key = rng.choice(keys + ["rendrer", "", "psf_fwhm ", "x" * 100])
        out[key] = rng.choice(scalars(np) + ["image", "airy", "moffat", "exact", "true", "1", "0.05", "-1", "nan",
                                             "2", "0", "3", "1,2", "options"])
    return out


# --- the cases -----------------------------------------------------------------------------------

echoed = [0]  # the longest text argument of the last case


def one_case(case, seed, files):
    import numpy as np
    import stampede

    rng = random.Random(seed * 1_000_003 + case)
    keys = sorted(stampede.option_help())
    pool = scalars(np)
    stamps = files["stamps"]
    cell = files["cell"]

    # Most arguments valid and one or two hostile, so that cases reach the layers behind the
    # argument checks (the fits, the runs, the readers) as well as the checks themselves.
    hostile_rate = rng.choice([0.05, 0.15, 0.4])
    valid = {"int": lambda: rng.choice([0, 1, 2, 3, np.int32(2)]),
             "real": lambda: rng.choice([0.0, 0.01, 1.0, 2.85, 3, 40.0]),
             "flag": lambda: rng.choice([True, False, np.bool_(True)]),
             "text": lambda: rng.choice(["bd", "disc", "bulge", "b+d"]),
             "path": lambda: rng.choice([files["grid"], pathlib.Path(files["grid"]), files["dir"] + "/out.fits",
                                         files["fit"], files["tile"]]),
             "options": lambda: options(rng, np, keys),
             "stamps": lambda: rng.choice([stamps, stamps[:1], stamps.astype("f4"), stamps[:, ::-1]]),
             "stamp": lambda: rng.choice([stamps[0], stamps[1].T, stamps[2].astype("f4")]),
             "weights": lambda: rng.choice([np.ones_like(stamps), np.full(stamps.shape, 0.5)]),
             "weight": lambda: rng.choice([np.ones_like(stamps[0]), np.full(stamps[0].shape, 2.0)]),
             "psf": lambda: rng.choice([None, files["psf"], np.repeat(files["psf"][None], len(stamps), axis=0)]),
             "e": lambda: rng.choice([np.zeros(4), np.arange(4.0) * 0.01]),
             "usable": lambda: np.ones(4, dtype=int),
             "pair": lambda: np.array([0, 0, 1, 1]),
             "progress": lambda: rng.choice([None, lambda *a: None]),
             "shard": lambda: rng.choice([None, (0, 2), (1, 2), [np.int64(0), 3]]),
             "paths": lambda: [files["fit"]],
             "sets": lambda: [dict(g1_true=0.01 * k, g2_true=-0.01 * k, g1=0.011 * k, g2=-0.01 * k, err1=1e-3, err2=1e-3)
                              for k in range(rng.choice([2, 3]))],
             "id": lambda: rng.choice([0, 7, 2**62]),
             "size": lambda: rng.choice([8, 8, 9, 12]),
             "cell": lambda: rng.choice([cell["image"], cell["image"].astype("f4"), cell["image"][::-1]]),
             "cell_weight": lambda: rng.choice([cell["weight"], None if rng.random() < 0.1 else cell["weight"] * 2]),
             "cell_psf": lambda: rng.choice([cell["psf"], cell["psf"].astype("f4")]),
             "cell_plane": lambda: rng.choice([None, np.zeros_like(cell["image"]), cell["noise"]]),
             "cell_size": lambda: rng.choice([64, 48, 40]),
             "scale": lambda: rng.choice([0.2, 0.263, np.float32(0.25)]),
             "noise_sigma": lambda: rng.choice([1.0, 0.5, 3.0]),
             "detector": lambda: rng.choice(["tree", "sep"]),
             "measurement": lambda: rng.choice(["wmom", "pgauss", "exp"]),
             "reconvolution": lambda: rng.choice(["auto", "gauss"]),
             "table": lambda: rng.choice([files["md"], pathlib.Path(files["md"])]),
             "minus": lambda: rng.choice([None, files["md_minus"]]),
             "shear": lambda: rng.choice([None, (0.02, 0.0), [0.02, 0], np.array([0.02, 0.0])]),
             "estimator": lambda: rng.choice(["composed", "package"]),
             "bands": lambda: rng.choice([[0], (0,), np.array([0])]),
             "layout": lambda: rng.choice(["table", "package"])}
    hostile = {"int": lambda: rng.choice([-1, 2**31, 2**40, 2**63, 10**6, 4097, np.uint64(2**64 - 1), True, 2.0]),
               "real": lambda: rng.choice([math.nan, math.inf, -1.0, 1e308, 0.0, "1", np.longdouble(2), 1j]),
               "flag": lambda: rng.choice([1, 0, "True", None, np.array([True])]),
               "text": lambda: rng.choice(["", "x\0", "BD", "x" * 5000]),
               "path": lambda: path(rng, files),
               "options": lambda: rng.choice([3, "renderer=exact", ["renderer"], {1: 2}, {"x" * 100: 1}]),
               "stamps": lambda: rng.choice([stamps[:, :4, :5], array(rng, np, 3, 8), array(rng, np)]),
               "stamp": lambda: rng.choice([stamps[0, :5, :4], array(rng, np, 2, 8), array(rng, np)]),
               "weights": lambda: rng.choice([-np.ones_like(stamps), np.full(stamps.shape, np.nan), array(rng, np, 3, 8)]),
               "weight": lambda: rng.choice([-np.ones_like(stamps[0]), np.zeros_like(stamps[0]), array(rng, np, 2, 8)]),
               "psf": lambda: rng.choice([files["psf"][None, :3], array(rng, np, rng.choice([2, 3])),
                                          np.full_like(files["psf"], np.nan), np.zeros_like(files["psf"])]),
               "e": lambda: rng.choice([np.zeros(3), array(rng, np, 1, 4), np.full(4, np.nan)]),
               "usable": lambda: rng.choice([np.ones(3), np.array(["a"] * 4), np.full(4, 2**40)]),
               "pair": lambda: rng.choice([np.array([0, 1, 2, 3]), np.array([-1, -1, 5, 5]), np.zeros(4)]),
               "progress": lambda: rng.choice([raising_callback, 5, print, lambda: None]),
               "shard": lambda: rng.choice([(2, 2), (0,), "0/2", (0, 10**7), (-1, 2), (0.5, 2)]),
               "paths": lambda: rng.choice([[files["fit"], files["fit"]], files["fit"], [], [3], [files["grid"]]]),
               "sets": lambda: rng.choice([[], [{}], "sets", [{"g1": "x"}] * 2, [None, None]]),
               "id": lambda: rng.choice([-1, 2**63, 2**64, 1.5]),
               "size": lambda: rng.choice([0, 1, 7, 513, 10**6, -8, 8.0]),
               "cell": lambda: rng.choice([cell["image"][:10], cell["image"][:, :40], np.full((64, 64), np.nan),
                                           np.zeros((0, 64)), array(rng, np, 2, 64), array(rng, np),
                                           cell["image"] + 50.0]),
               "cell_weight": lambda: rng.choice([-cell["weight"], np.zeros_like(cell["weight"]),
                                                  np.full((64, 64), np.inf), cell["weight"][:5], array(rng, np, 2, 64)]),
               "cell_psf": lambda: rng.choice([cell["psf"][:24, :24], cell["psf"][2:, :], np.zeros((25, 25)),
                                               np.full((25, 25), np.nan), array(rng, np, 2, 25), np.ones((1, 1))]),
               "cell_plane": lambda: rng.choice([np.ones((3, 3)), cell["noise"] * 100, np.full((64, 64), np.nan),
                                                 array(rng, np, 2, 64)]),
               "cell_size": lambda: rng.choice([0, 1, -64, 65, 10**6, 2**31, 64.0, 17]),
               "scale": lambda: rng.choice([0.0, -0.2, math.inf, math.nan, 1e-300, 1e300, "0.2"]),
               "noise_sigma": lambda: rng.choice([0.0, -1.0, math.nan, math.inf, 1e-300]),
               "detector": lambda: rng.choice(["", "SEP", "x\0", "tree "]),
               "measurement": lambda: rng.choice(["", "gauss", "WMOM", "bd\0"]),
               "reconvolution": lambda: rng.choice(["", "moffat", "x" * 3000]),
               "table": lambda: rng.choice([files["fit"], files["grid"], path(rng, files), files["md"] + ".partial"]),
               "minus": lambda: rng.choice([files["md"], files["fit"], path(rng, files)]),
               "shear": lambda: rng.choice([(math.nan, 0), "0.02,0", (1,), (2.0, 0), (0.02, 0, 0), {}]),
               "estimator": lambda: rng.choice(["", "Composed", "x\0"]),
               "bands": lambda: rng.choice([[], [1], [-1], [0.5], ["0"], [2 ** 40], np.array([[0]]), None]),
               "layout": lambda: rng.choice(["", "Package", "x\0", 0])}

    # Parameters whose valid values are narrower than their type's: (valid values, hostile kind).
    narrow = {"min_area": ([1, 4, 6], "int"), "levels": ([8, 32], "int"), "filter_size": ([3, 5, 7], "int"),
              "box_min": ([17, 33], "int"), "box_max": ([63, 255], "int"), "fwhm": ([0.0, 1.2, 2.0], "real"),
              "threshold": ([0.8, 1.5, 3.0], "real"), "contrast": ([1e-5, 0.005], "real"),
              "step": ([0.01, 0.02], "real"), "dilation": ([0.0, 1.2], "real"), "buffer": ([8, 4], "int"),
              "cut": ([10.0, 1.2, 0.5], "real"), "resamples": ([2, 50], "int")}

    def value(kind):
        if kind in narrow:
            allowed, kind_hostile = narrow[kind]
            r = rng.random()
            if r < hostile_rate * 0.3:
                return rng.choice(pool)
            return hostile[kind_hostile]() if r < hostile_rate else rng.choice(allowed)
        r = rng.random()
        if r < hostile_rate * 0.3:
            return rng.choice(pool)
        if r < hostile_rate:
            return hostile[kind]()
        return valid[kind]()

    signatures = {
        "fit_stamps": [("stamps", "stamps"), ("weights", "weights"), ("psf", "psf"), ("psf_oversampling", "int"),
                       ("psf_pixel_integrated", "flag"), ("options", "options"), ("threads", "int"),
                       ("grid_nx", "int"), ("first_id", "id")],
        "fit_stamp": [("stamp", "stamp"), ("weight", "weight"), ("psf", "psf"), ("psf_oversampling", "int"),
                      ("psf_pixel_integrated", "flag"), ("options", "options")],
        "Fitter": [("options", "options"), ("stamp_size", "size"), ("psf", "psf"), ("psf_oversampling", "int"),
                   ("psf_pixel_integrated", "flag")],
        "run_fit": [("input", "path"), ("output", "path"), ("catalog", "path"), ("weight", "path"),
                    ("text_output", "path"), ("options", "options"), ("threads", "int"), ("resume", "flag"),
                    ("overwrite", "flag"), ("progress", "progress"), ("shard", "shard"), ("meds", "path")],
        "merge_shards": [("shards", "paths"), ("output", "path"), ("overwrite", "flag")],
        "simulate_great08": [("set", "int"), ("grid", "int"), ("stamp_size", "size"), ("snr", "real"),
                             ("noise_sigma", "real"), ("noise_free", "flag"), ("size_ratio", "real"),
                             ("galaxy_type", "text"), ("e_max", "real"), ("psf_fwhm", "real"), ("psf_beta", "real"),
                             ("seed", "int")],
        "set_shear": [("e1", "e"), ("e2", "e"), ("usable", "usable"), ("pair", "pair"), ("g1_true", "real"),
                      ("g2_true", "real"), ("bootstrap", "int"), ("seed", "int")],
        "shear_metrics": [("sets", "sets"), ("psf_e1", "real"), ("psf_e2", "real")],
        "read_image": [("path", "path")],
        "read_results": [("path", "path")],
        "Options": [("options", "options")],
        "Options.from_ini": [("path", "path")],
        "detect": [("image", "cell"), ("noise_sigma", "noise_sigma"), ("detector", "detector"),
                   ("detect_threshold", "threshold"), ("detect_min_area", "min_area"),
                   ("deblend_contrast", "contrast"), ("deblend_thresholds", "levels"), ("filter_fwhm", "fwhm"),
                   ("filter_size", "filter_size"), ("clean", "flag")],
        "metadetect": [("image", "cell"), ("weight", "cell_weight"), ("psf", "cell_psf"), ("pixel_scale", "scale"),
                       ("bmask", "cell_plane"), ("threads", "int"), ("cell_size", "cell_size"),
                       ("cell_buffer", "buffer"), ("step", "step"), ("reconvolution_psf", "reconvolution"),
                       ("psf_dilation", "dilation"), ("fixnoise", "flag"), ("double_images", "flag"), ("seed", "int"),
                       ("measurement", "measurement"), ("weight_fwhm", "fwhm"), ("recentre", "flag"),
                       ("detector", "detector"), ("detect_threshold", "threshold"), ("detect_min_area", "min_area"),
                       ("deblend_contrast", "contrast"), ("deblend_thresholds", "levels"), ("filter_fwhm", "fwhm"),
                       ("filter_size", "filter_size"), ("clean", "flag"), ("stamp_size", "size"),
                       ("box_min", "box_min"), ("box_max", "box_max"), ("per_object_metacal", "flag"),
                       ("noise", "cell_plane"), ("ormask", "cell_plane"), ("mfrac", "cell_plane"), ("detect_bands", "bands"),
                       ("shear_bands", "bands"), ("layout", "layout")],
        "metadetect_metrics": [("table", "table"), ("minus", "minus"), ("rotated", "minus"),
                               ("rotated_minus", "minus"), ("shear", "shear"), ("cut_snr", "cut"),
                               ("cut_t_ratio", "cut"), ("bootstrap", "resamples"), ("seed", "int"),
                               ("estimator", "estimator")],
    }
    name = rng.choice(sorted(signatures))
    params = signatures[name]
    args, kwargs = [], {}
    positional = rng.randrange(len(params) + 1) if name not in ("simulate_great08",) else rng.choice([0, 1])
    required = {"fit_stamps": 1, "fit_stamp": 1, "merge_shards": 2, "set_shear": 6, "shear_metrics": 1,
                "read_image": 1, "read_results": 1, "Options.from_ini": 1, "run_fit": 2, "detect": 2,
                "metadetect": 4, "metadetect_metrics": 1}.get(name, 0)
    positional = max(positional, required if rng.random() < 0.7 else 0)
    # Keyword-only parameters past these (a positional one there is a TypeError, drawn rarely).
    keyword_only = {"detect": 2, "metadetect": 6}.get(name)
    if keyword_only is not None and rng.random() < 0.95:
        positional = min(positional, keyword_only)
    for k, (param, kind) in enumerate(params):
        if k < positional:
            args.append(value(kind))
        elif rng.random() < (0.2 if len(params) > 12 else 0.5) or (k < required and rng.random() < 0.9):
            kwargs[param] = value(kind)
    if rng.random() < 0.05:
        kwargs[rng.choice(["thread", "stamp_sise", "weigths", "x"])] = 1
    if rng.random() < 0.03:
        args.append(1)
    names = [param for param, _ in params]
    defaults = {"simulate_great08": {"grid": 1, "stamp_size": 8},  # keep the draws small
                "fit_stamps": {"threads": 1}, "run_fit": {"threads": 1},
                # one 64-pixel cell (the default 251 would take seconds a case); 50 resamples
                "metadetect": {"threads": 1, "cell_size": 64, "cell_buffer": 8},
                "metadetect_metrics": {"bootstrap": 50}}.get(name, {})
    for param, v in defaults.items():
        if names.index(param) >= len(args):
            kwargs.setdefault(param, v)
    # A valid large grid is legitimate work at the simulator's ~35 ms per galaxy (grid 39: 45 s),
    # not a hang (harness finding H2): valid sizes above 4 become 2; invalid ones stay.
    if name == "simulate_great08" and "grid" in kwargs:
        g = kwargs["grid"]
        if isinstance(g, (int, np.integer)) and not isinstance(g, bool) and 4 < g <= 1000:
            kwargs["grid"] = 2

    texts = list(args) + list(kwargs.values())
    texts += [v for d in texts if isinstance(d, dict) for v in d.values()]  # option values, e.g. paths
    echoed[0] = max([len(v) for v in texts if isinstance(v, str)] + [0])
    target = {"Fitter": stampede.Fitter, "Options": stampede.Options,
              "Options.from_ini": stampede.Options.from_ini}.get(name) or getattr(stampede, name)
    result = target(*args, **kwargs)
    if name == "Fitter":
        fit_args = [value("stamp")] + ([value("weight")] if rng.random() < 0.3 else [])
        result.fit(*fit_args, **({"id": value("id")} if rng.random() < 0.3 else {}))
    if name == "Options" and rng.random() < 0.5:
        result[rng.choice([3, "renderer", "nope", None])]
    return name


def classify(error, echoed):
    """None if the exception is an acceptable answer to bad arguments, else why it is a finding.
    `echoed`: the length of the longest text argument, which a message may quote once."""
    import stampede

    message = str(error)
    if isinstance(error, ZeroDivisionError):
        return None  # an argument's own __index__, __float__, __fspath__ or callback raised: passed on
    if not isinstance(error, (TypeError, ValueError, stampede.Error)):
        return f"{type(error).__name__}: {message[:300]}"
    if len(message) > MAX_MESSAGE + echoed:
        return f"a {len(message)}-character message: {message[:200]}..."
    if "array(" in message:
        return f"an array printed in the message: {message[:300]}"
    return None


# --- the worker and the driver -------------------------------------------------------------------

def make_files(work):
    import numpy as np
    import stampede

    cli = os.environ.get("STAMPEDE_CLI", "build/tools/stampede")
    work = tempfile.mkdtemp(dir=work)  # each worker its own files: a case may have overwritten the last's
    subprocess.run([cli, "sim", "great08", "--out", work + "/sim", "--sets", "1", "--grid", "2", "--stamp", "8",
                    "--threads", "1"], check=True, capture_output=True)
    grid = work + "/sim/set_0.fits"
    fit = work + "/fit.fits"
    subprocess.run([cli, "fit", grid, "-o", fit, "--set", "noise_sigma=1", "--set", "renderer=upsampled",
                    "--set", "upsampling=1", "--threads", "1", "--quiet"], check=True, capture_output=True)
    os.makedirs(work + "/out", exist_ok=True)
    sim = stampede.simulate_great08(grid=2, stamp_size=8)
    # A copy of the sample tile (with its PSFEx models): a case may name any of its files as an
    # output with overwrite=True, which replaces it, as asked. The fuzzer never hands out shared data.
    shutil.copytree(os.path.join(os.environ.get("STAMPEDE_DATA_DIR", "../shared/data"), "meds-sample"),
                    work + "/meds-sample", ignore=shutil.ignore_patterns("src", "truth.fits"))
    tile = work + "/meds-sample/meds.fits"
    # Metadetection: a 64-pixel cell in memory (noise, a few galaxies, a Gaussian PSF) and the
    # tables of a shear pair of two such cells.
    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[0:64, 0:64]
    image = rng.normal(0, 1, (64, 64))
    for cx, cy in ((20, 22), (41, 30), (30, 45)):
        image += 40 * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / 8.0)
    py, px = np.mgrid[0:25, 0:25]
    psf = np.exp(-((px - 12) ** 2 + (py - 12) ** 2) / 8.0)
    cell = {"image": image, "weight": np.ones((64, 64)), "psf": psf / psf.sum(), "noise": rng.normal(0, 1, (64, 64))}
    subprocess.run([cli, "sim", "cells", "--out", work + "/cells", "--cells", "2", "--size", "64", "--buffer", "8",
                    "--grid", "2", "--pair", "--threads", "1"], check=True, capture_output=True)
    md = {}
    for side, where in (("md", "/cells"), ("md_minus", "/cells/minus")):
        md[side] = work + "/" + side + ".fits"
        cells = sorted(str(p) for p in pathlib.Path(work + where).glob("cell_*.fits"))
        subprocess.run([cli, "metadetect", *cells, "-o", md[side], "--cell-size", "64", "--cell-buffer", "8",
                        "--threads", "1", "--quiet"], check=True, capture_output=True)
    return {"grid": grid, "fit": fit, "dir": work + "/out", "tile": tile, "stamps": sim["stamps"],
            "psf": sim["psf_image"], "cell": cell, **md}


def worker(seed, first, count, work, status_path, timeout):
    import faulthandler
    import warnings

    warnings.simplefilter("ignore")
    files = make_files(work)
    faulthandler.enable()
    for case in range(first, first + count):
        with open(status_path, "w") as f:
            f.write(str(case))
        faulthandler.dump_traceback_later(timeout, exit=True)
        try:
            one_case(case, seed, files)
        except BaseException as e:  # noqa: BLE001 - every exception is classified
            if isinstance(e, KeyboardInterrupt):
                raise
            why = classify(e, echoed[0])
            if why:
                print(json.dumps({"case": case, "finding": why, "traceback": traceback.format_exc()[-2000:]}),
                      flush=True)
        faulthandler.cancel_dump_traceback_later()
    with open(status_path, "w") as f:
        f.write("done")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--cases", type=int, default=2000, help="cases to run (ignored with --cpu-seconds)")
    p.add_argument("--cpu-seconds", type=float, default=0, help="run until workers used this much CPU")
    p.add_argument("--chunk", type=int, default=500, help="cases per worker process")
    p.add_argument("--case-timeout", type=float, default=60)
    p.add_argument("--findings", default="")
    p.add_argument("--replay", type=int, default=-1, help="run one case in this process, with its traceback")
    p.add_argument("--worker", nargs=3, type=int, metavar=("FIRST", "COUNT", "UNUSED"), help=argparse.SUPPRESS)
    p.add_argument("--work", default="", help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.worker:
        worker(a.seed, a.worker[0], a.worker[1], a.work, a.work + "/status", a.case_timeout)
        return 0
    with tempfile.TemporaryDirectory(prefix="stampede-pyfuzz-") as work:
        if a.replay >= 0:
            print(one_case(a.replay, a.seed, make_files(work)))
            return 0
        findings, case, started = [], 0, time.time()
        while (case < a.cases) if a.cpu_seconds <= 0 else (cpu_used() < a.cpu_seconds):
            count = a.chunk if a.cpu_seconds > 0 else min(a.chunk, a.cases - case)
            if os.path.exists(work + "/status"):
                os.remove(work + "/status")
            r = subprocess.run([sys.executable, __file__, "--seed", str(a.seed), "--worker", str(case), str(count), "0",
                                "--work", work, "--case-timeout", str(a.case_timeout)], capture_output=True, text=True)
            new = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
            status = open(work + "/status").read().strip() if os.path.exists(work + "/status") else "?"
            if status != "done":  # the worker died at case `status`: a crash or a hang
                at = int(status) if status.isdigit() else case
                kind = f"signal {-r.returncode}" if r.returncode < 0 else f"exit {r.returncode}"
                new.append({"case": at, "finding": f"worker died ({kind})", "traceback": r.stderr[-3000:]})
                case = at + 1
            else:
                case += count
            for f in new:  # reported as found, so that a run stopped early loses none
                print(f"case {f['case']}: {f['finding']}", file=sys.stderr, flush=True)
            findings += new
            if a.findings and new:
                os.makedirs(a.findings, exist_ok=True)
                with open(os.path.join(a.findings, f"python_arguments_seed{a.seed}.json"), "w") as out:
                    json.dump(findings, out, indent=1)
            print(f"cases {case}, findings {len(findings)}, worker CPU {cpu_used():.0f} s, "
                  f"wall {time.time() - started:.0f} s", file=sys.stderr, flush=True)
        print(f"{case} cases, {len(findings)} findings, worker CPU {cpu_used():.0f} s")
        return 1 if findings else 0


def cpu_used():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


if __name__ == "__main__":
    sys.exit(main())
