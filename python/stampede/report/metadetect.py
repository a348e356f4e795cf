"""The metadetection page: `stampede metadetect` tables (a METADETECT HDU), checked and streamed
once for their counts per shear type before and after the cuts, the distributions the cuts act on,
detections per cell and flags; R, g and, for a shear pair, m and c from stampede.metadetect_metrics,
the code of `stampede metrics --metadetect`, so the page's numbers are the command's."""

import math
import os

import numpy as np

import stampede
from stampede import FitsError

from . import figures
from .fits_file import FitsFile
from .inputs import ReportError, checked_table
from .page import Page, note, pre, table
from .statistics import Histogram

# `stampede metrics --metadetect`'s cuts (MetadetectCuts, engine/analysis/metadetect_shear.hpp): flags
# 0, snr > CUT_SNR, T_ratio > CUT_T_RATIO, mfrac <= CUT_MFRAC, e finite; given to metadetect_metrics
# explicitly, so the page's counts and its metrics are of one selection.
CUT_SNR = 10.0
CUT_T_RATIO = 1.2
CUT_MFRAC = 0.1
BOOTSTRAP = 200  # its defaults: --bootstrap 200, --seed 1
SEED = 1
SHEAR_TYPES = ("noshear", "1p", "1m", "2p", "2m")  # MetacalType order
REQUIRED_COLUMNS = ("cell", "shear_type", "id", "e1", "e2", "T_ratio", "snr", "mfrac", "flags")
STREAMED = REQUIRED_COLUMNS
FLAG_MEANINGS = {0: "moments failed", 1: "edge", 2: "masked at the detection", 3: "cell failed"}  # io/metadetect_writer
# Header keys of the run's options (app/metadetect_run option_keys), shown folded.
OPTION_KEYS = ("CELLSIZE", "CELLBUF", "MCSTEP", "MCPSFDIL", "FIXNOISE", "PEROBJMC", "NOISEPLN", "MCSEED", "WFWHM",
               "DETECTOR", "DETTHR", "DETMINA", "DBLCONT", "DBLNTHR", "FILTFWHM", "FILTSIZE", "CLEAN", "CLEANPAR", "BOXRFAC",
               "BOXRMIN", "BOXPAD", "BOXMIN", "BOXMAX")


def is_metadetect(path):
    """Whether `path` is a `stampede metadetect` table (it has a METADETECT HDU); a file that cannot
    be read is a ReportError naming it."""
    try:
        return FitsFile(str(path)).hdu("METADETECT") is not None
    except FitsError as e:
        raise ReportError(str(e)) from None


class MetadetectTable:
    """One `stampede metadetect` table: its METADETECT header and columns, checked."""

    def __init__(self, path):
        self.path = str(path)
        self.table = checked_table(
            self.path, "METADETECT", REQUIRED_COLUMNS, "`stampede metadetect` table",
            lambda fits: f"{self.path}: no METADETECT HDU: not a `stampede metadetect` table")
        self.header = self.table.header
        self.rows = self.table.rows
        step = self.header.get("MCSTEP")
        self.step = step if isinstance(step, (int, float)) and not isinstance(step, bool) else math.nan
        if not 0 < self.step <= 0.1:
            raise ReportError(f"{self.table.where}: header key MCSTEP = {step!r} is not a metacal step in (0, 0.1]")
        self.bands = str(self.header.get("BANDS", "")) or "one"

    def chunks(self, chunk_rows):
        try:
            for start, chunk in self.table.chunks(STREAMED, chunk_rows):
                yield start, self._checked(chunk, start)
        except FitsError as e:
            raise ReportError(str(e)) from None

    def _checked(self, chunk, first_row):
        """shear_type one of the five (its index, 0..4), cell, id and flags integers (flags >= 0), as
        `stampede metrics --metadetect` reads them; a value it would refuse, or none writes, names the
        column and row."""
        types = np.asarray(chunk["shear_type"])
        index = np.full(types.size, -1, dtype=np.int64)
        for k, name in enumerate(SHEAR_TYPES):
            index[types == name] = k
        if (index < 0).any():
            i = int(np.argmax(index < 0))
            raise ReportError(f"{self.table.where}: column 'shear_type' row {first_row + i} = {types[i]!r} is not one "
                              f"of {' '.join(SHEAR_TYPES)}")
        chunk["shear_type"] = index
        for name, lo in (("cell", -2**62), ("id", -1), ("flags", 0)):
            v = np.asarray(chunk[name])
            if v.dtype.kind == "f":
                with np.errstate(invalid="ignore"):
                    good = (v >= lo) & (v == np.floor(v)) & (np.abs(v) < 2.0**62)
                if not np.all(good):
                    i = int(np.argmin(good))
                    raise ReportError(f"{self.table.where}: column '{name}' row {first_row + i} = {v[i]} is not an "
                                      "integer")
                v = v.astype(np.int64)
            if name == "flags" and (v < 0).any():
                i = int(np.argmax(v < 0))
                raise ReportError(f"{self.table.where}: column 'flags' row {first_row + i} = {v[i]} is negative")
            chunk[name] = v
        for name in ("e1", "e2", "snr", "T_ratio"):
            chunk[name] = np.asarray(chunk[name], dtype=np.float64)
        return chunk

    def options(self):
        return [(k, self.header[k]) for k in OPTION_KEYS if k in self.header]


def kept_by_cuts(c):
    """The rows `stampede metrics --metadetect` keeps (engine/analysis/metadetect_shear.cpp)."""
    with np.errstate(invalid="ignore"):
        return (c["flags"] == 0) & (c["snr"] > CUT_SNR) & (c["T_ratio"] > CUT_T_RATIO) & \
            (c["mfrac"] <= CUT_MFRAC) & np.isfinite(c["e1"]) & np.isfinite(c["e2"])


class MetadetectCounts:
    """One table's numbers from every row in fixed-size state (cells: a count per cell)."""

    def __init__(self):
        self.detections = np.zeros(5, dtype=np.int64)  # id >= 0, per shear type
        self.flags0 = np.zeros(5, dtype=np.int64)
        self.kept = np.zeros(5, dtype=np.int64)
        self.e_sums = np.zeros((5, 2))  # kept rows' sums of e1, e2
        self.flag_bits = np.zeros(32, dtype=np.int64)  # detections with each bit set
        self.failed_cells = set()
        self.per_cell = {}  # cell -> noshear detections

    def add(self, c):
        detected = c["id"] >= 0
        kept = kept_by_cuts(c)
        t = c["shear_type"]
        self.detections += np.bincount(t[detected], minlength=5)
        self.flags0 += np.bincount(t[detected & (c["flags"] == 0)], minlength=5)
        self.kept += np.bincount(t[kept], minlength=5)
        for k in (0, 1):
            self.e_sums[:, k] += np.bincount(t[kept], weights=c[f"e{k + 1}"][kept], minlength=5)
        flags = c["flags"][detected]
        for b in range(32):
            self.flag_bits[b] += int(np.count_nonzero(flags & (1 << b)))
        self.failed_cells.update(np.unique(c["cell"][~detected]).tolist())
        cells, counts = np.unique(c["cell"][detected & (t == 0)], return_counts=True)
        for cell in np.unique(c["cell"]).tolist():
            self.per_cell.setdefault(cell, 0)
        for cell, n in zip(cells.tolist(), counts.tolist()):
            self.per_cell[cell] += n

    def mean_e(self):
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.e_sums / self.kept[:, None]


class MetadetectInputs:
    """The metadetection tables of one report: one table, or a shear pair (plus, then minus), with
    the true shear of the pair (None: the plus table's first input's G1, G2 keys, as the command)."""

    def __init__(self, paths, shear=None):
        if len(paths) > 2:
            raise ReportError(f"{len(paths)} metadetect tables given ({', '.join(map(str, paths))}): give one table, "
                              "or a shear pair: the +g table, then the -g one")
        self.tables = [MetadetectTable(p) for p in paths]
        if len(self.tables) == 2:
            plus, minus = self.tables
            if plus.step != minus.step:
                raise ReportError(f"{minus.path} was run with another metacal step (MCSTEP {minus.step}) than "
                                  f"{plus.path} ({plus.step}): not a shear pair")
        self.shear = shear


def metrics(path, minus=None, shear=None, cuts=True):
    """stampede.metadetect_metrics with the command's defaults; without `cuts` only flags 0 (and e
    finite) select. Errors are ReportErrors naming the files."""
    kw = {"minus": minus} if minus else {}
    if shear is not None and minus:
        kw["shear"] = list(shear)
    limits = (CUT_SNR, CUT_T_RATIO, CUT_MFRAC) if cuts else (-math.inf, -math.inf, math.inf)
    try:
        return stampede.metadetect_metrics(path, cut_snr=limits[0], cut_t_ratio=limits[1], cut_mfrac=limits[2],
                                           bootstrap=BOOTSTRAP, seed=SEED, **kw)
    except (stampede.Error, ValueError) as e:
        what = f"{path} and {minus}" if minus else path
        raise ReportError(f"metrics of {what}: {e}") from None


def number_text(v, spec):
    """C printf's rendering of a double, which the command prints: 'nan'/'inf' as glibc writes them."""
    if math.isnan(v):
        return ("-" if math.copysign(1.0, v) < 0 else ("+" if spec.startswith("+") else "")) + "nan"
    return format(v, spec)


def printed_lines(path, r, minus=None):
    """The lines `stampede metrics --metadetect PATH [--minus MINUS]` prints for its result `r`
    (tools/metadetect_metrics_command.cpp), so the page and the command compare as text."""
    lines = [f"{path}: {r['cells']} cells, {r['kept_noshear']:.0f} noshear rows kept (snr > {CUT_SNR:g}, "
             f"T_ratio > {CUT_T_RATIO:g}, mfrac <= {CUT_MFRAC:g}, flags 0)",
             f"  R11 = {number_text(r['R11'], '.5f')} +- {number_text(r['R11_err'], '.5f')}   "
             f"R22 = {number_text(r['R22'], '.5f')} +- {number_text(r['R22_err'], '.5f')}",
             f"  g1  = {number_text(r['g1'], '+.3e')} +- {number_text(r['g1_err'], '.1e')}   "
             f"g2 = {number_text(r['g2'], '+.3e')} +- {number_text(r['g2_err'], '.1e')}"]
    if "m1" in r:
        lines.append(f"shear pair with {minus}, g = ({r['shear'][0]:g}, {r['shear'][1]:g}), {r['pairs']} pairs of "
                     f"cells, estimator {r['estimator']}:")
        for m, c in (("m1", "c2"), ("m2", "c1")):
            if math.isfinite(r[m]):
                lines.append(f"  {m} = {number_text(r[m], '+.3e')} +- {number_text(r[m + '_err'], '.1e')}   "
                             f"{c} = {number_text(r[c], '+.3e')} +- {number_text(r[c + '_err'], '.1e')}")
    return lines


def compute(inputs, chunk_rows, progress=None):
    """Every number of the page: per table its counts and histograms (one pass), its metrics with
    and without the S/N and T_ratio cuts, and the pair's."""
    out = {"counts": [], "hist": {"snr": Histogram("S/N (snr), noshear detections", -25.0, 25.0, 10000,
                                                   asinh_scale=1.0),
                                  "T_ratio": Histogram("T_ratio, noshear detections", -25.0, 25.0, 10000,
                                                       asinh_scale=0.1)}}
    for t in inputs.tables:
        counts = MetadetectCounts()
        for start, c in t.chunks(chunk_rows):
            counts.add(c)
            noshear = (c["shear_type"] == 0) & (c["id"] >= 0)
            for name in ("snr", "T_ratio"):
                out["hist"][name].add(c[name][noshear])
            if progress:
                progress(t.path, start + c["id"].size, t.rows)
        out["counts"].append(counts)
    out["single"] = [metrics(t.path) for t in inputs.tables]
    out["no_cuts"] = [metrics(t.path, cuts=False) for t in inputs.tables]
    if len(inputs.tables) == 2:
        out["pair"] = metrics(inputs.tables[0].path, minus=inputs.tables[1].path, shear=inputs.shear)
    return out


def write_page(inputs, out, chunk_rows, progress=None):
    """The metadetection report: its figures into `out` and the Page, returned."""
    n = compute(inputs, chunk_rows, progress)
    names = [os.path.basename(t.path) for t in inputs.tables]
    labels = ["+g", "-g"] if len(names) == 2 else [""]
    page = Page(f"stampede report: {', '.join(names)} (metadetection)")
    cuts_section(page, inputs, n, names, out)
    response_section(page, inputs, n, names, labels, out)
    return page, n


def cuts_section(page, inputs, n, names, out):
    counts = n["counts"]
    per_cell = np.array([v for c in counts for v in c.per_cell.values()], dtype=np.float64)
    bits = np.sum([c.flag_bits for c in counts], axis=0)
    figures.metadetect_cuts(n["hist"]["snr"], n["hist"]["T_ratio"], CUT_SNR, CUT_T_RATIO, per_cell,
                            [(f"{1 << b} {FLAG_MEANINGS.get(b, '?')}", int(bits[b])) for b in range(32) if bits[b]],
                            os.path.join(out, "metadetect_cuts.png"))
    overview = [(name, t.rows, len(c.per_cell), len(c.failed_cells), t.step, t.bands,
                 str(t.header.get("INPUTS", "")), str(t.header.get("INPUT1", "")))
                for name, t, c in zip(names, inputs.tables, counts)]
    type_rows = []
    for name, c in zip(names, counts):
        mean = c.mean_e()
        for k, kind in enumerate(SHEAR_TYPES):
            share = f"{100 * c.kept[k] / c.detections[k]:.1f} %" if c.detections[k] else "–"
            type_rows.append((name, kind, int(c.detections[k]), int(c.flags0[k]), int(c.kept[k]), share, mean[k, 0],
                              mean[k, 1]))
    detections = int(sum(c.detections.sum() for c in counts))
    flag_rows = [(f"{1 << b} (bit {b})", FLAG_MEANINGS.get(b, "?"), int(bits[b]),
                  f"{100 * bits[b] / max(1, detections):.2f} %") for b in range(32) if bits[b]]
    options = inputs.tables[0].options()
    page.section("Metadetection: detections and cuts", "metadetect_cuts.png",
                 [table(overview, ["table", "rows", "cells", "failed cells", "MCSTEP", "bands", "INPUTS", "INPUT1"],
                        text_columns=(0, 5, 6, 7)),
                  table(flag_rows, ["flag", "meaning", "detections", "share"], text_columns=(0, 1)) if flag_rows
                  else note("No flags set.")],
                 [table(type_rows, ["table", "shear type", "detections", "flags 0", "after cuts", "kept", "⟨e1⟩ kept",
                                    "⟨e2⟩ kept"], text_columns=(0, 1, 5)),
                  "<details><summary>options of the run (first table)</summary>" +
                  table([(k, str(v)) for k, v in options], ["option", "value"], text_columns=(0, 1)) + "</details>",
                  note(f"Detections: rows with id ≥ 0 (a cell that could not be measured is one row with id −1 and "
                       f"flag 8). Cuts as `stampede metrics --metadetect`: flags 0, snr > {CUT_SNR:g}, T_ratio > "
                       f"{CUT_T_RATIO:g}, mfrac ≤ {CUT_MFRAC:g}, e finite; each shear type's catalogue is cut on its own quantities. "
                       "Histograms: noshear detections of every table; detections per cell: noshear, per cell and "
                       "table.")])


def response_section(page, inputs, n, names, labels, out):
    counts = n["counts"]
    figures.metadetect_response([c.mean_e() for c in counts], labels, SHEAR_TYPES,
                                [(r["R11"], r["R22"]) for r in n["single"]], inputs.tables[0].step,
                                os.path.join(out, "metadetect_response.png"))
    rows = []
    for name, r, free in zip(names, n["single"], n["no_cuts"]):
        for key in ("R11", "R22"):
            rows.append((name, key, r[key], r[key + "_err"], free[key], free[key + "_err"], r[key] - free[key]))
    shear_rows = [(name, r["g1"], r["g1_err"], r["g2"], r["g2_err"], int(r["kept_noshear"]))
                  for name, r in zip(names, n["single"])]
    beside = [table(rows, ["table", "", "with the cuts", "σ", "flags 0 only", "σ", "response of the cuts"],
                    text_columns=(0, 1)),
              table(shear_rows, ["table", "g1", "σ", "g2", "σ", "noshear kept"])]
    lines = printed_lines(inputs.tables[0].path, n["single"][0])
    if "pair" in n:
        p = n["pair"]
        # As the command prints them: m1 and c2 for a shear along g1, m2 and c1 along g2.
        bias = [(k, p[k], p[k + "_err"]) for m, c in (("m1", "c2"), ("m2", "c1")) if math.isfinite(p[m])
                for k in (m, c)]
        beside.append(table(bias, [f"pair: g = ({p['shear'][0]:g}, {p['shear'][1]:g}), {p['pairs']} pairs of cells",
                                   "", "σ"]))
        lines = printed_lines(inputs.tables[0].path, p, inputs.tables[1].path)
    page.section("Metadetection: response and shear (stampede metrics --metadetect)", "metadetect_response.png",
                 beside,
                 [pre(lines),
                  note("R11 = (⟨e1⟩_1p − ⟨e1⟩_1m) / (2 MCSTEP), R22 likewise, g = ⟨e⟩_noshear / R; for a shear pair "
                       "m = (⟨e1⟩₊ − ⟨e1⟩₋) / 2 / ⟨R11⟩ / g1 − 1 and c2 = (⟨e2⟩₊ + ⟨e2⟩₋) / 2 / ⟨R22⟩ (m2, c1 for a "
                       "shear along g2). Errors: bootstrap over cells (200 resamples, seed 1; a pair's two cells "
                       "together). Computed by the command's code (stampede.metadetect_metrics): the lines above are "
                       "what `stampede metrics --metadetect` prints for these tables. 'Flags 0 only': the same without "
                       "the S/N and T_ratio cuts; their difference is the part of R that the cuts' selection "
                       "contributes. Figure: each type's ⟨e⟩ minus noshear's (kept rows); the sheared types should "
                       "sit near ±MCSTEP × R (dashes).")])
