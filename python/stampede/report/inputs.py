"""The report's inputs, checked before anything is written: `stampede fit` result tables, the truth
files of simulated sets, and a `save_images` file. Every refusal is a ReportError naming the file
(and HDU or column)."""

import glob
import math
import os

import numpy as np

from stampede import FitsError

from .fits_file import FitsFile

# Columns every result table has (io/result_columns.hpp); a table without them is not one.
REQUIRED_COLUMNS = ("id", "e1", "e2", "radius", "snr", "chi2", "n_iter", "status", "flags")
# The fit options whose *_FREE key says whether the parameter was fitted (io/run_config).
PARAMETERS = ("X0", "Y0", "E1", "E2", "RADIUS", "BULGE_A", "DISC_A", "RADIUS_RATIO", "BULGE_INDEX", "DISC_INDEX",
              "DELTA_E", "DELTA_THETA")
# Header keys that identify the run and its inputs rather than configure it.
IDENTITY_KEYS = ("INPUT", "INDIGEST", "INSETID", "CATALOG", "CATDIGST", "WEIGHT", "WGTDIGST", "MEDS", "MEDSDIGS",
                 "RUNFP", "SHARD", "SHARDTOT", "VERSION")


class ReportError(Exception):
    """A user error: bad input or output, with a message naming the file."""


def simulation_identity(header):
    """The simulated set a truth file describes, as `stampede fit` records its input's (INSETID):
    'SEED=s SETIDX=k NOISESD=n' (a grid's) or 'SIMID=hex' (a `sim meds` tile's) from the keys
    present (io/simulation_identity.cpp)."""
    def integer(v):  # as FitsFile::read_key_long: an integer, or a real with an integer value
        if isinstance(v, float) and v.is_integer():
            return int(v)
        if isinstance(v, int) and not isinstance(v, bool):
            return v
        raise ValueError(v)

    parts = [f"{k}={integer(header[k])}" for k in ("SEED", "SETIDX", "NOISESD") if k in header]
    if "SIMID" in header:
        parts.append(f"SIMID={header['SIMID']}")
    return " ".join(parts)


def checked_table(path, extname, required, what, no_hdu):
    """The table HDU `extname` of `path`, with every `required` column and a row at least; else a
    ReportError naming the file (`no_hdu(fits)` its message when the HDU is absent) and `what` the
    table should have been. A run's unfinished table (NAME.partial, .checkpoint, .lock, or a table
    with a checkpoint beside it) is refused: its rows are not the run's."""
    path = str(path)
    for suffix in (".partial", ".checkpoint", ".checkpoint.tmp", ".lock"):
        if path.endswith(suffix):
            raise ReportError(f"{path}: a run's unfinished {suffix[1:]} file, not a {what}: finish that run "
                              "(--resume) and give its table")
    if os.path.exists(path + ".checkpoint"):
        raise ReportError(f"{path}: a run that replaces it is unfinished ('{path}.checkpoint' is beside it), so "
                          f"it is not a finished {what}: finish that run (--resume) first")
    try:
        fits = FitsFile(path)
        t = fits.table(extname)
    except FitsError as e:
        raise ReportError(str(e)) from None
    if t is None:
        raise ReportError(no_hdu(fits))
    missing = [c for c in required if not t.has(c)]
    if missing:
        raise ReportError(f"{t.where}: no column {', '.join(repr(c) for c in missing)}: not a {what}")
    if t.rows == 0:
        raise ReportError(f"{t.where}: the table has no rows: nothing to report")
    return t


class ResultTable:
    """One `stampede fit` table: its RESULTS header and columns, what kind of input it fitted."""

    def __init__(self, path):
        self.path = str(path)
        def no_hdu(fits):
            names = ", ".join(h["name"] or f"HDU {h['index']}" for h in fits.hdus)
            return f"{self.path}: not a `stampede fit` result table (no RESULTS HDU; it has {names})"

        self.table = checked_table(self.path, "RESULTS", REQUIRED_COLUMNS, "`stampede fit` result table", no_hdu)
        self.header = self.table.header
        self.rows = self.table.rows
        self.survey = self.table.has("ra") and self.table.has("dec")
        self.metacal = self.table.has("R11")
        if self.metacal:
            missing = [c for c in ("R12", "R21", "R22") if not self.table.has(c)]
            if missing:
                raise ReportError(f"{self.table.where}: metacal column 'R11' without {', '.join(map(repr, missing))}: "
                                  "not a `stampede fit` metacal table")
        # The sheared images' step (metacal_step, 0.01 by default), which R is measured over.
        step = self.header.get("metacal_step", self.header.get("METACAL_STEP", 0.01)) if self.metacal else 0.01
        try:
            self.metacal_step = float(step)
        except (TypeError, ValueError):
            self.metacal_step = math.nan
        if not 0 < self.metacal_step <= 0.1:
            raise ReportError(f"{self.table.where}: metacal_step = {step!r} is not a metacal step in (0, 0.1]")
        self.positions = "survey" if self.survey else "catalogue" if self.table.has("x_image") else "grid"
        self.set_identity = str(self.header.get("INSETID", ""))

    def has(self, column):
        return self.table.has(column)

    def chunks(self, columns, chunk_rows):
        try:
            for start, chunk in self.table.chunks([c for c in columns if self.table.has(c)], chunk_rows):
                yield start, self._integers(chunk, start)
        except FitsError as e:
            raise ReportError(str(e)) from None

    def read(self, columns):
        try:
            return self._integers(self.table.read([c for c in columns if self.table.has(c)]), 0)
        except FitsError as e:
            raise ReportError(str(e)) from None

    def _integers(self, chunk, first_row):
        """status and flags as the fit wrote them, int64: a value none writes (NaN, 2.5, a status past
        the table's STATUSn keys, a negative flag word) is a damaged table, named by column and row;
        the other columns as float64."""
        last_status = max(self.status_names(), default=6)
        for name, lo, hi in (("status", 0, last_status), ("flags", 0, 2**32 - 1)):
            if name not in chunk:
                continue
            v = np.asarray(chunk[name])
            with np.errstate(invalid="ignore"):
                good = (v >= lo) & (v <= hi) & ((v == np.floor(v)) if v.dtype.kind == "f" else True)
            if not np.all(good):
                i = int(np.argmin(good))
                raise ReportError(f"{self.table.where}: column '{name}' row {first_row + i} = {v[i]} is not an "
                                  f"integer in [{lo}, {hi}]")
            chunk[name] = v.astype(np.int64)
        for name in chunk:  # the measured columns as reals, whatever type a table gives them (an e of J)
            if name not in ("id", "status", "flags"):
                chunk[name] = np.asarray(chunk[name], dtype=np.float64)
        return chunk

    def status_names(self):
        return {int(k[6:]): str(v) for k, v in self.header.values.items() if k.startswith("STATUS") and k[6:].isdigit()}

    def flag_meanings(self):
        """{bit: meaning} from the table's COMMENT cards 'flags bit B (V): meaning'."""
        out = {}
        for line in self.header.comments:
            if line.startswith("flags bit ") and "): " in line:
                bit = line[len("flags bit "):].split(" ", 1)[0]
                if bit.isdigit():
                    out[int(bit)] = line.split("): ", 1)[1]
        return out

    def options(self):
        """The run's configuration: the header keys from RENDERER (the first option) on, less the
        identity keys, in card order."""
        keys = self.header.order
        start = keys.index("RENDERER") if "RENDERER" in keys else len(keys)
        return [(k, self.header[k]) for k in keys[start:] if k not in IDENTITY_KEYS]

    def identity(self):
        return [(k, self.header[k]) for k in IDENTITY_KEYS if k in self.header]

    def free_parameters(self):
        return sum(1 for p in PARAMETERS if str(self.header.get(f"{p}_FREE", "false")).lower() == "true")

    def pixels_per_object(self):
        """Pixels in one stamp (grid and catalogue input: STAMP_SIZE^2); None for survey tables,
        whose pixel count per object depends on its epochs and is not recorded."""
        size = self.header.get("STAMP_SIZE")
        # A size without room for the free parameters is a damaged header: no pixel count, as a survey's.
        if self.survey or not isinstance(size, int) or isinstance(size, bool) or size * size <= self.free_parameters():
            return None
        return size * size


def check_distinct(tables):
    """Each file once, by its resolved path and its identity on disk (a link or a second name of one
    file counts too)."""
    seen = {}
    for t in tables:
        st = os.stat(t.path)
        for key in (("path", os.path.realpath(t.path)), ("inode", st.st_dev, st.st_ino)):
            if key in seen:
                raise ReportError(f"{t.path} is given twice (as {seen[key].path} too): each table is pooled once")
            seen[key] = t


def check_tables(tables):
    """The tables pooled into one report: each file once (by its resolved path and its identity on
    disk, so a link or a second name of one file counts too), and of one kind of input: a survey
    (MEDS) table's radii are arcsec and its chi2 has no pixel count, a grid or catalogue table's are
    pixels and chi2/dof, so the two are never pooled into one histogram."""
    check_distinct(tables)
    survey = [t for t in tables if t.survey]
    if survey and len(survey) != len(tables):
        other = next(t for t in tables if not t.survey)
        raise ReportError(f"{survey[0].path} is a survey (MEDS) table (radius in arcsec, no pixel count for chi2/dof) "
                          f"but {other.path} is a {other.positions} table (radius in pixels): report them separately")
    return tables


class Truth:
    """A simulated set's truth (GREAT08-mini layout): SHEAR1 SHEAR2 in the primary header and a
    TRUTH table with index and pair."""

    def __init__(self, path):
        self.path = str(path)
        try:
            fits = FitsFile(self.path)
            primary = fits.header(0)
            self.table = fits.table("TRUTH")
        except FitsError as e:
            raise ReportError(f"truth {e}") from None
        if "SHEAR1" not in primary or "SHEAR2" not in primary:
            raise ReportError(f"{self.path}[HDU 0]: no SHEAR1/SHEAR2 keys: not the truth file of a simulated set")
        try:
            self.g1, self.g2 = float(primary["SHEAR1"]), float(primary["SHEAR2"])
        except (TypeError, ValueError):
            self.g1 = self.g2 = math.nan
        if not (abs(self.g1) < 1 and abs(self.g2) < 1):
            raise ReportError(f"{self.path}[HDU 0]: SHEAR1, SHEAR2 = {primary['SHEAR1']!r}, {primary['SHEAR2']!r} is "
                              "not a shear (numbers with |g| < 1)")
        try:
            self.identity = simulation_identity(primary)
        except (TypeError, ValueError):
            raise ReportError(f"{self.path}[HDU 0]: SEED, SETIDX or NOISESD is not an integer: not a simulation's "
                              "identity") from None
        if self.table is None or not self.table.has("index"):
            raise ReportError(f"{self.path}: no TRUTH table with an 'index' column: not the truth file of a simulated set")

    def read(self, columns):
        try:
            out = self.table.read([c for c in columns if self.table.has(c)])
        except FitsError as e:
            raise ReportError(f"truth {e}") from None
        if "pair" in out:  # ring-pair labels are integers; NaN or 2.5 is a damaged file
            v = np.asarray(out["pair"])
            good = np.isfinite(v) & (v == np.floor(v)) & (np.abs(v) < 2.0**53) if v.dtype.kind == "f" else \
                np.ones(v.shape, bool)
            if not np.all(good):
                i = int(np.argmin(good))
                raise ReportError(f"{self.table.where}: column 'pair' row {i} = {v[i]} is not an integer")
            out["pair"] = v.astype(np.int64)
        return out


def match_truth(tables, truth_arg):
    """Each table's Truth, from --truth: a file (one table) or a directory of truth files, matched
    to each table by the set it fitted (INSETID), else by the input's name (set_K -> truth_K).
    A truth of another set than the table's is refused, as `stampede metrics` refuses it."""
    if os.path.isdir(truth_arg):
        candidates = sorted(glob.glob(os.path.join(truth_arg, "*truth*.fits")))
        if not candidates:
            raise ReportError(f"--truth {truth_arg}: the directory holds no truth files (*truth*.fits)")
        truths = [Truth(p) for p in candidates]
        by_identity = {t.identity: t for t in truths if t.identity}
        by_name = {os.path.basename(t.path).replace("truth", "set", 1): t for t in truths}
        out = []
        for table in tables:
            truth = by_identity.get(table.set_identity) if table.set_identity else None
            if truth is None and not table.set_identity:
                truth = by_name.get(os.path.basename(str(table.header.get("INPUT", ""))))
            if truth is None:
                what = f"a fit of set '{table.set_identity}' (INSETID)" if table.set_identity else \
                    f"a fit of '{table.header.get('INPUT', '?')}'"
                raise ReportError(f"{table.path} is {what}, but no truth file in {truth_arg} is of that set: "
                                  "give the truth of the run that made the table")
            out.append(truth)
    else:
        if len(tables) != 1:
            raise ReportError(f"--truth {truth_arg} is one file but {len(tables)} tables were given: give the "
                              "directory of the simulation's truth files")
        out = [Truth(truth_arg)]
    for table, truth in zip(tables, out):
        if table.set_identity and truth.identity and table.set_identity != truth.identity:
            raise ReportError(f"{table.path} is a fit of set '{table.set_identity}' (INSETID), but {truth.path} is the "
                              f"truth of set '{truth.identity}': give each fit its own set's truth")
        if truth.table.rows != table.rows:
            raise ReportError(f"{table.path} has {table.rows} rows, {truth.table.where} has {truth.table.rows}: "
                              "not the truth of this fit")
    return out


class SavedImages:
    """A `save_images` file (HDUs DATA_id MODEL_id RESID_id) and the table it belongs to: the one
    whose output it sits beside (OUT.fits -> OUT.images.fits)."""

    def __init__(self, path, tables):
        self.path = str(path)
        try:
            self.fits = FitsFile(self.path)
        except FitsError as e:
            raise ReportError(str(e)) from None
        self.hdus = {h["name"]: h for h in self.fits.hdus}
        self.ids = sorted(int(n[5:]) for n in self.hdus if n.startswith("DATA_") and n[5:].lstrip("-").isdigit()
                          and f"MODEL_{n[5:]}" in self.hdus and f"RESID_{n[5:]}" in self.hdus)
        if not self.ids:
            raise ReportError(f"{self.path}: no DATA_id/MODEL_id/RESID_id HDUs: not a `save_images` file")
        self.table = None
        for table in tables:
            base = table.path[:-5] if table.path.endswith(".fits") else table.path
            beside = base + ".images.fits"
            if os.path.exists(beside) and os.path.samefile(beside, self.path):
                self.table = table
        if self.table is None:
            raise ReportError(f"{self.path}: not the save_images file of any table given (a fit OUT.fits writes "
                              "OUT.images.fits beside it)")

    def images(self, object_id):
        try:
            return [self.fits.image(self.hdus[f"{kind}_{object_id}"]) for kind in ("DATA", "MODEL", "RESID")]
        except FitsError as e:
            raise ReportError(str(e)) from None
