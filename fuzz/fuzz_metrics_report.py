#!/usr/bin/env python3
"""Property fuzzer for `stampede metrics` and the report's inputs (docs/reliability.md).

Every case takes real inputs (`stampede sim great08` sets fitted plain, with save_images and with
metacal, and a `sim meds` tile fitted as a survey table, each with its truth file), damages some
of them as a FITS file can be damaged (column values NaN, inf, 1e308, out-of-range integers;
columns dropped, renamed, retyped or made vectors; rows cut, repeated, reordered; header keys
removed or given other types; HDUs renamed; bytes flipped or the file cut short) and runs
`stampede metrics` (as a process) or the report (`stampede.report`'s command-line main, in the
worker) on them with options drawn from valid and hostile values. A finding is:
  - metrics killed by a signal, an exit status other than 0 or 1, a run past --case-timeout;
  - an error message not starting with the command's prefix, over 600 characters beyond the paths
    it names, or C++'s "terminate called";
  - metrics exiting 0 with a bare nan or inf in its output (a value not computed is n/a), or a
    --json file that is not strict JSON (NaN is null);
  - the report raising anything but its own ReportError (a traceback), a refused report leaving a
    directory or temporary behind, a report replacing a file that is not its own;
  - any input file changed by a case (the base inputs are digested after every case).
Cases are numbered and drawn from random.Random(seed * 1_000_003 + case), so any case replays alone:
    fuzz/fuzz_metrics_report.py --replay CASE [--seed S]

usage: fuzz/fuzz_metrics_report.py [--seed S] [--cases N | --cpu-seconds T] [--findings DIR]
The module comes from PYTHONPATH (build/python) and the `stampede` command from STAMPEDE_CLI.
Run it with /usr/bin/python3 (astropy writes the damaged tables).
"""

import argparse
import contextlib
import hashlib
import io
import json
import math
import os
import random
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
import warnings

MAX_MESSAGE = 600
CLI = os.environ.get("STAMPEDE_CLI", "build/tools/stampede")
REPORT_FILES = {"report.html", "status.png", "distributions.png", "psf_leakage.png", "e_vs_truth.png",
                "bias_bins.png", "metacal_R.png", "residuals.png"}


# --- the base inputs -----------------------------------------------------------------------------

def run(*args):
    subprocess.run([CLI, *args], check=True, capture_output=True)


def make_files(work):
    """Real inputs, made once per worker: four GREAT08-layout sets in two shear pairs fitted plain
    (set 0 saving images), set 0 fitted with metacal, a 4-object `sim meds` tile fitted."""
    base = tempfile.mkdtemp(dir=work)
    cheap = ["--set", "renderer=upsampled", "--set", "upsampling=1", "--set", "n_central_pixels_to_upsample=0",
             "--set", "padding=0", "--threads", "1", "--quiet"]
    run("sim", "great08", "--out", base + "/sim", "--sets", "4", "--grid", "4", "--stamp", "24", "--snr", "40",
        "--galaxy", "disc", "--threads", "1", "--shear-pairs")
    f = {"dir": base, "sim": base + "/sim"}
    for k in range(4):
        extra = ["--set", "save_images=0,1,2"] if k == 0 else []
        run("fit", f"{base}/sim/set_{k}.fits", "-o", f"{base}/fit_{k}.fits", *cheap, *extra)
        f[f"fit_{k}"], f[f"truth_{k}"] = f"{base}/fit_{k}.fits", f"{base}/sim/truth_{k}.fits"
    f["images"] = base + "/fit_0.images.fits"
    run("fit", f"{base}/sim/set_0.fits", "-o", f"{base}/mcal.fits", "--set", "metacal=true", "--threads", "1", "--quiet")
    f["mcal"] = base + "/mcal.fits"
    run("sim", "meds", "--out", base + "/meds", "--objects", "4", "--epochs", "2", "--snr", "30", "--threads", "1")
    run("fit", "--meds", base + "/meds/meds.fits", "-o", base + "/survey.fits", "--threads", "1", "--quiet")
    f["survey"], f["survey_truth"] = base + "/survey.fits", base + "/meds/truth.fits"
    f["digests"] = digests(base)
    return f


def digests(top):
    out = {}
    for root, _, names in os.walk(top):
        for n in names:
            p = os.path.join(root, n)
            with open(p, "rb") as fh:
                out[p] = hashlib.sha256(fh.read()).hexdigest()
    return out


# --- damage --------------------------------------------------------------------------------------

FLOATS = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1e308, -1e308, 5e-324, 1e162, -1.0, 0.5, 2.0**31, 2.0**53 + 2,
          1e-300, 7.0]
INTS = [0, -1, 1, 7, 8, 99, 2**31 - 1, -2**31, 2**53 + 1, 2**62, -2**63, 4194304, 262144, 0xFFFFFFFF]
HEADER_VALUES = [0, -1, 1, 0.01, 1e300, -1e300, 1e-300, "x", "", " ", "0.01", "nan", "T", True, False, 2**62,
                 "x" * 300, "SEED=7 SETIDX=0 NOISESD=0", "SIMID=0123456789abcdef", "g,r", "b0,B0", "1/2"]
RESULT_KEYS = ["metacal_step", "metacal_gamma_fwhm", "INSETID", "STATUS0", "STATUS3", "BANDS", "STAMP_SIZE",
               "RENDERER", "SHARD", "SHARDTOT", "RUNFP", "METACAL", "E1_FREE", "MEDS", "INPUT", "TFIELDS"]
TRUTH_KEYS = ["SHEAR1", "SHEAR2", "SEED", "SETIDX", "NOISESD", "SHEARPR", "SIMID", "NOISEFRE"]


def damage_table(rng, np, fits, src, dst, truth):
    """A copy of `src` at `dst` with 1-3 kinds of damage (the table HDU is RESULTS, or TRUTH)."""
    extname = "TRUTH" if truth else "RESULTS"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        hdus = fits.open(src)
        hdus = fits.HDUList([h.copy() for h in hdus])
        for _ in range(rng.choice([1, 1, 2, 3])):
            kind = rng.choice(["value", "value", "value", "dtype", "drop", "rename", "rows", "rows", "key", "key",
                               "hdu", "bytes"])
            tab_index = next((i for i, h in enumerate(hdus) if h.name == extname and hasattr(h, "columns")), None)
            if tab_index is None:
                break
            try:
                damage_once(rng, np, fits, hdus, tab_index, kind, extname, truth)
            except (ValueError, TypeError, KeyError, IndexError, AttributeError):
                pass  # astropy refused this damage: the next one, or the file as it stands
        try:
            hdus.writeto(dst, overwrite=True, output_verify="silentfix")
        except Exception:  # noqa: BLE001 - astropy refused the damage it was asked for: write the original
            shutil.copyfile(src, dst)
    if rng.random() < 0.08:  # bytes: flipped, or the file cut short
        data = bytearray(open(dst, "rb").read())
        if rng.random() < 0.5 and data:
            for _ in range(rng.randrange(1, 8)):
                data[rng.randrange(len(data))] = rng.randrange(256)
        else:
            data = data[:rng.randrange(len(data) + 1)]
        open(dst, "wb").write(bytes(data))
    return dst


def damage_once(rng, np, fits, hdus, tab_index, kind, extname, truth):
    tab = hdus[tab_index]
    cols = list(tab.columns.names)
    if kind == "value" and cols and tab.data is not None and len(tab.data):
        name = rng.choice(cols)
        col = tab.data[name]
        n = len(col)
        rows = rng.choice([slice(None), [rng.randrange(n)], rng.sample(range(n), k=max(1, n // 2))])
        if col.dtype.kind in "iu":
            col[rows] = rng.choice(INTS) if col.dtype.itemsize == 8 else rng.choice([0, -1, 99, 7])
        elif col.dtype.kind == "f":
            v = rng.choice(FLOATS + ["normal"])
            col[rows] = np.random.default_rng(rng.randrange(1 << 30)).normal(size=n)[rows] if v == "normal" else v
        elif col.dtype.kind == "b":
            col[rows] = rng.choice([True, False])
    elif kind in ("dtype", "drop", "rename") and cols:
        name = rng.choice(cols)
        arrays = []
        for c in tab.columns:
            data = tab.data[c.name] if tab.data is not None else np.zeros(0)
            if c.name != name:
                arrays.append(fits.Column(name=c.name, format=c.format, array=data))
            elif kind == "rename":
                new = rng.choice([name.upper(), name.lower() + "_", name.capitalize(), "e1", "id", "x" * 68])
                arrays.append(fits.Column(name=new, format=c.format, array=data))
            elif kind == "dtype":
                fmt = rng.choice(["E", "D", "J", "K", "I", "B", "L", "8A", "2D"])
                try:
                    if fmt == "8A":
                        arr = np.array([str(x)[:8] for x in data])
                    elif fmt == "L":
                        arr = np.asarray(data) != 0
                    elif fmt == "2D":
                        arr = np.repeat(np.asarray(data, dtype=float)[:, None], 2, axis=1)
                    elif fmt in "JKIB":
                        with np.errstate(all="ignore"):
                            arr = np.nan_to_num(np.asarray(data, dtype=float)).astype(
                                {"J": "i4", "K": "i8", "I": "i2", "B": "u1"}[fmt])
                    else:
                        arr = np.asarray(data, dtype={"E": "f4", "D": "f8"}[fmt])
                    arrays.append(fits.Column(name=name, format=fmt, array=arr))
                except (TypeError, ValueError):
                    arrays.append(fits.Column(name=c.name, format=c.format, array=data))
        new_tab = fits.BinTableHDU.from_columns(arrays, header=tab.header, name=extname)
        hdus[tab_index] = new_tab
    elif kind == "rows" and tab.data is not None:
        n = len(tab.data)
        how = rng.choice(["cut", "repeat", "reverse", "shuffle"])
        if how == "cut":
            idx = list(range(min(n, rng.choice([0, 1, 2, 3, n - 1]))))
        elif how == "repeat":
            idx = list(range(n)) + list(range(rng.randrange(1, n + 1))) if n else []
        elif how == "reverse":
            idx = list(range(n))[::-1]
        else:
            idx = rng.sample(range(n), k=n)
        hdus[tab_index] = fits.BinTableHDU(data=tab.data[idx], header=tab.header, name=extname)
    elif kind == "key":
        h = hdus[0].header if (truth and rng.random() < 0.8) else tab.header
        keys = TRUTH_KEYS if truth else RESULT_KEYS
        key = rng.choice(keys + [k for k in h.keys() if k not in ("SIMPLE", "XTENSION", "BITPIX", "NAXIS",
                                                                   "NAXIS1", "NAXIS2", "PCOUNT", "GCOUNT",
                                                                   "TFIELDS", "EXTEND", "END", "")][:40])
        if key in ("TFIELDS",):
            return
        if rng.random() < 0.3:
            h.remove(key, ignore_missing=True, remove_all=True)
        else:
            try:
                h[key] = rng.choice(HEADER_VALUES)
            except (ValueError, TypeError, KeyError):
                pass
        if rng.random() < 0.1:
            h.add_comment(rng.choice(["flags bit 4 (16): x", "flags bit x (y): z", "flags bit 99999999999 (1): "
                                      "w", "flags bit ", "flags bit 3 (8)"]))
    elif kind == "hdu":
        how = rng.choice(["rename", "extra_before", "drop"])
        if how == "rename":
            hdus[tab_index].name = rng.choice(["RESULT", "results", "OTHER", "TRUTH" if not truth else "RESULTS"])
        elif how == "extra_before":
            hdus.insert(1, fits.ImageHDU(np.zeros((2, 2)), name=extname))
        elif len(hdus) > 1:
            del hdus[tab_index]


def maybe_damaged(rng, np, fits, files, key, case_dir, truth=False, rate=0.5):
    src = files[key]
    if rng.random() >= rate:
        return src
    dst = os.path.join(case_dir, f"{key}_{rng.randrange(1 << 20)}.fits")
    return damage_table(rng, np, fits, src, dst, truth)


# --- one case --------------------------------------------------------------------------------------

def number_value(rng):
    return rng.choice(["10", "0", "-5", "1e308", "-1e308", "nan", "inf", "-inf", "x", "", "0x10", "1e-300", "3",
                       "20", "2.5", "1,2", " 7"])


def metrics_case(rng, np, fits, files, case_dir):
    kind = rng.choice(["plain", "plain", "pairs", "metacal", "survey"])
    if kind in ("plain", "pairs"):
        n = 4 if kind == "pairs" else rng.choice([1, 2, 2, 3, 4])
        sets = list(range(4)) if kind == "pairs" else rng.sample(range(4), k=n)
        pairs = [(maybe_damaged(rng, np, fits, files, f"fit_{k}", case_dir, rate=0.3),
                  maybe_damaged(rng, np, fits, files, f"truth_{k}", case_dir, truth=True, rate=0.3)) for k in sets]
    elif kind == "metacal":
        pairs = [(maybe_damaged(rng, np, fits, files, "mcal", case_dir), maybe_damaged(rng, np, fits, files, "truth_0",
                                                                                       case_dir, truth=True, rate=0.2))]
        if rng.random() < 0.5:
            pairs.append((files["fit_1"], files["truth_1"]))
    else:
        pairs = [(maybe_damaged(rng, np, fits, files, "survey", case_dir),
                  maybe_damaged(rng, np, fits, files, "survey_truth", case_dir, truth=True, rate=0.3))]
    if rng.random() < 0.1 and len(pairs) > 1:  # another set's truth
        a, b = rng.sample(range(len(pairs)), 2)
        pairs[a] = (pairs[a][0], pairs[b][1])
    args = []
    for fit, truth in pairs:
        args += ["--fit", fit, "--truth", truth]
    if rng.random() < 0.05:
        args += ["--fit", pairs[0][0]] + (["--truth", pairs[0][1]] if rng.random() < 0.5 else [])
    if kind == "pairs" or rng.random() < 0.05:
        args.append("--shear-pairs")
    if kind == "metacal" or rng.random() < 0.05:
        args.append("--metacal")
        if rng.random() < 0.2:
            args.append("--no-selection-response")
    json_path = None
    for option, p in [("--cut-snr", 0.15), ("--cut-radius", 0.1), ("--cut-size-ratio", 0.1), ("--bootstrap", 0.2),
                      ("--seed", 0.1), ("--e-columns", 0.1), ("--json", 0.4)]:
        if rng.random() >= p:
            continue
        if option == "--bootstrap":
            v = rng.choice(["0", "1", "2", "3", "50", "-1", "1000001", "x", "1e3"])
        elif option == "--seed":
            v = rng.choice(["0", "7", "-1", "9223372036854775807", "9223372036854775808", "x"])
        elif option == "--e-columns":
            v = rng.choice(["e1,e2", "e2,e1", "e1_cal,e2_cal", "snr,radius", "id,id", "e1", "e1,e2,e3", ",", "E1,E2",
                            "status,flags", "R11,R22"])
        elif option == "--json":
            v = rng.choice([os.path.join(case_dir, "out.json")] * 6 + [case_dir, pairs[0][0], pairs[0][1],
                                                                         os.path.join(case_dir, "no/such/dir/x.json"),
                                                                         pairs[0][0] + "[1]"])
            json_path = v
        else:
            v = number_value(rng)
        args += [option, v]
        if rng.random() < 0.03:
            args += [option, v]
    if rng.random() < 0.03:
        args.append(rng.choice(["--bogus", "--fit", "--json", "--cut-snr"]))
    if rng.random() < 0.05:
        rng.shuffle(args)
    protected = set(p for pair in pairs for p in pair) - base_paths(files)
    before = {p: digest(p) for p in protected if os.path.isfile(p)}
    r = subprocess.run([CLI, "metrics", *args], capture_output=True, text=True, errors="replace",
                       timeout=CASE_TIMEOUT)
    problems = []
    if r.returncode < 0:
        problems.append(f"metrics killed by signal {-r.returncode}")
    elif r.returncode not in (0, 1):
        problems.append(f"metrics exit {r.returncode}")
    longest = max([len(a) for a in args] + [0])
    if "terminate called" in r.stderr:
        problems.append("terminate called: " + r.stderr[-300:])
    if r.returncode == 1:
        if not r.stderr.startswith("stampede metrics: error: "):
            problems.append("error without the command's prefix: " + r.stderr[:300])
        if len(r.stderr) > MAX_MESSAGE + 2 * longest:
            problems.append(f"a {len(r.stderr)}-character error: {r.stderr[:200]}")
    if r.returncode == 0:
        # Q = 1e-4 / mean squared residual is infinite for residuals of exactly zero: a value, not a failure.
        for word in r.stdout.replace("Q = inf ", "").replace("(", " ").replace(")", " ").replace(",", " ").split():
            if word.lstrip("+-").lower() in ("nan", "inf", "-nan", "infinity"):
                problems.append("a bare non-finite value in the output: " + r.stdout[-600:])
                break
        if json_path and os.path.isfile(json_path) and json_path.endswith(".json"):
            try:
                json.loads(open(json_path).read(), parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
            except ValueError as e:
                problems.append(f"--json is not strict JSON: {e}")
    for p, d in before.items():
        if not os.path.isfile(p) or digest(p) != d:
            problems.append(f"input {p} was changed")
    return "metrics " + " ".join(args), problems


def base_paths(files):
    return {v for v in files.values() if isinstance(v, str)}


def digest(path):
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def snapshot(directory):
    return digests(directory) if os.path.isdir(directory) else None


def report_case(rng, np, fits, files, case_dir):
    from stampede.report.__main__ import main as report_main

    pool = ["fit_0", "fit_1", "fit_2", "fit_3", "mcal", "survey"]
    keys = rng.sample(pool, k=rng.choice([1, 1, 2, 3]))
    tables = [maybe_damaged(rng, np, fits, files, k, case_dir, rate=0.6) for k in keys]
    if rng.random() < 0.05:
        tables.append(tables[0])
    args = list(tables)
    truth_dir = None
    r = rng.random()
    if r < 0.3:
        args += ["--truth", files["sim"]]
    elif r < 0.5:
        key = {"survey": "survey_truth", "mcal": "truth_0"}.get(keys[0], keys[0].replace("fit", "truth"))
        args += ["--truth", maybe_damaged(rng, np, fits, files, key, case_dir, truth=True, rate=0.5)]
    elif r < 0.6:  # a directory of (possibly damaged) truth files
        truth_dir = os.path.join(case_dir, "truths")
        os.makedirs(truth_dir)
        for k in range(4):
            t = maybe_damaged(rng, np, fits, files, f"truth_{k}", case_dir, truth=True, rate=0.3)
            shutil.copyfile(t, os.path.join(truth_dir, f"truth_{k}.fits"))
        args += ["--truth", truth_dir]
    elif r < 0.63:
        args += ["--truth", rng.choice([os.path.join(case_dir, "none"), files["fit_0"], "", files["images"]])]
    if rng.random() < 0.1:
        args += ["--images", rng.choice([files["images"], files["fit_0"], os.path.join(case_dir, "none.fits")])]
    # The output: new, an existing report (with or without --overwrite), a directory holding other
    # files, the directory of the inputs.
    out_kind = rng.choice(["new", "new", "new", "report", "other", "inputs"])
    out = os.path.join(case_dir, "out")
    if out_kind in ("report", "other"):
        os.makedirs(out)
        if out_kind == "report":
            for name in rng.sample(sorted(REPORT_FILES), k=3):
                open(os.path.join(out, name), "w").write("old " + name)
        else:
            open(os.path.join(out, "notes.txt"), "w").write("mine")
            if rng.random() < 0.5:
                open(os.path.join(out, "report.html"), "w").write("old")
    elif out_kind == "inputs":
        out = case_dir
    args += ["-o", out]
    if rng.random() < 0.5:
        args.append("--overwrite")
    args.append("--quiet")
    before_out = snapshot(out)
    protected = {p: digest(p) for p in tables if os.path.isfile(p) and p not in base_paths(files)}
    stderr = io.StringIO()
    problems = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
                code = report_main(args)
        except SystemExit as e:  # argparse
            code = e.code
        except Exception:  # noqa: BLE001 - any escaping exception is a finding
            code = None
            problems.append("traceback: " + traceback.format_exc()[-1500:])
    err = stderr.getvalue()
    for w in caught:
        if not issubclass(w.category, (DeprecationWarning, PendingDeprecationWarning)):
            problems.append(f"warning {w.category.__name__}: {str(w.message)[:200]} at {w.filename}:{w.lineno}")
    if code == 1:
        if not err.startswith("stampede.report: "):
            problems.append("error without the prefix: " + err[:300])
        if len(err) > MAX_MESSAGE + 2 * max(len(str(a)) for a in args):
            problems.append(f"a {len(err)}-character error: {err[:200]}")
        if snapshot(out) != before_out:
            problems.append(f"a refused report changed {out}")
    elif code == 0:
        after = snapshot(out) or {}
        if not os.path.isfile(os.path.join(out, "report.html")):
            problems.append("exit 0 without report.html")
        for p, d in (before_out or {}).items():
            if os.path.basename(p) not in REPORT_FILES and after.get(p) != d:
                problems.append(f"the report replaced or removed {p}, not one of its files")
    elif code not in (2, None):
        problems.append(f"exit {code}")
    leftovers = [n for n in os.listdir(os.path.dirname(os.path.abspath(out))) if n.startswith((".report-", ".old-report-"))]
    if leftovers:
        problems.append(f"temporaries left: {leftovers}")
    for p, d in protected.items():
        if not os.path.isfile(p) or digest(p) != d:
            problems.append(f"input {p} was changed")
    return "report " + " ".join(map(str, args)), problems


def one_case(case, seed, files, work):
    import numpy as np
    from astropy.io import fits

    rng = random.Random(seed * 1_000_003 + case)
    case_dir = tempfile.mkdtemp(dir=work, prefix=f"case{case}-")
    try:
        what, problems = (metrics_case if rng.random() < 0.6 else report_case)(rng, np, fits, files, case_dir)
    except subprocess.TimeoutExpired as e:
        what, problems = " ".join(map(str, e.cmd)), [f"past the {CASE_TIMEOUT} s case limit"]
    except Exception:  # noqa: BLE001 - the harness's own failure, reported apart from the commands'
        what, problems = "harness", ["harness: " + traceback.format_exc()[-1500:]]
    finally:
        if not REPLAY:
            shutil.rmtree(case_dir, ignore_errors=True)
    now = digests(files["dir"])  # files a case wrote beside the inputs (a --json there) are not changes
    changed = sorted(p for p, d in files["digests"].items() if now.get(p) != d)
    if changed:
        problems.append(f"a base input was changed: {changed[:3]}")
        files["digests"] = {p: now[p] for p in files["digests"] if p in now}
    return what, problems


# --- the worker and the driver -------------------------------------------------------------------

CASE_TIMEOUT = 60
REPLAY = False


def worker(seed, first, count, work, status_path, timeout):
    import faulthandler

    import matplotlib
    matplotlib.use("Agg")
    files = make_files(work)
    faulthandler.enable()
    for case in range(first, first + count):
        with open(status_path, "w") as f:
            f.write(str(case))
        faulthandler.dump_traceback_later(timeout * 2, exit=True)
        what, problems = one_case(case, seed, files, work)
        for p in problems:
            print(json.dumps({"case": case, "finding": p, "what": what[:2000]}), flush=True)
        faulthandler.cancel_dump_traceback_later()
    with open(status_path, "w") as f:
        f.write("done")


def main():
    global CASE_TIMEOUT, REPLAY
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--cases", type=int, default=200, help="cases to run (ignored with --cpu-seconds)")
    p.add_argument("--cpu-seconds", type=float, default=0, help="run until workers used this much CPU")
    p.add_argument("--chunk", type=int, default=200, help="cases per worker process")
    p.add_argument("--case-timeout", type=float, default=60)
    p.add_argument("--findings", default="")
    p.add_argument("--replay", type=int, default=-1, help="run one case in this process and keep its files")
    p.add_argument("--worker", nargs=2, type=int, metavar=("FIRST", "COUNT"), help=argparse.SUPPRESS)
    p.add_argument("--work", default="", help=argparse.SUPPRESS)
    a = p.parse_args()
    CASE_TIMEOUT = a.case_timeout
    if a.worker:
        worker(a.seed, a.worker[0], a.worker[1], a.work, a.work + "/status", a.case_timeout)
        return 0
    if a.replay >= 0:
        REPLAY = True
        work = tempfile.mkdtemp(prefix="stampede-mrfuzz-replay-")
        import matplotlib
        matplotlib.use("Agg")
        what, problems = one_case(a.replay, a.seed, make_files(work), work)
        print(what)
        print("\n".join(problems) or "no finding")
        print(f"(files kept in {work})")
        return 1 if problems else 0
    with tempfile.TemporaryDirectory(prefix="stampede-mrfuzz-") as work:
        findings, case, started = [], 0, time.time()
        while (case < a.cases) if a.cpu_seconds <= 0 else (cpu_used() < a.cpu_seconds):
            count = a.chunk if a.cpu_seconds > 0 else min(a.chunk, a.cases - case)
            if os.path.exists(work + "/status"):
                os.remove(work + "/status")
            r = subprocess.run([sys.executable, __file__, "--seed", str(a.seed), "--worker", str(case), str(count),
                                "--work", work, "--case-timeout", str(a.case_timeout)], capture_output=True, text=True)
            new = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
            status = open(work + "/status").read().strip() if os.path.exists(work + "/status") else "?"
            if status != "done":  # the worker died at case `status`: a crash or a hang
                at = int(status) if status.isdigit() else case
                kind = f"signal {-r.returncode}" if r.returncode < 0 else f"exit {r.returncode}"
                new.append({"case": at, "finding": f"worker died ({kind})", "what": r.stderr[-3000:]})
                case = at + 1
            else:
                case += count
            for f in new:  # reported as found, so that a run stopped early loses none
                print(f"case {f['case']}: {f['finding'][:300]}", file=sys.stderr, flush=True)
            findings += new
            if a.findings and new:
                os.makedirs(a.findings, exist_ok=True)
                with open(os.path.join(a.findings, f"metrics_report_seed{a.seed}.json"), "w") as out:
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
