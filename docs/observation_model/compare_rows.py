#!/usr/bin/env python3
"""Row comparisons for compare_rows.sh: a refactor must leave `stampede fit`'s output rows unchanged.

Reads FITS tables with the stampede module's own readers (fits_hdus, fits_header, read_table: float64
and int64 columns, so a D column's bits and a J/K column's values come through exactly) and .npy
structured arrays (fit_stamps' rows) with numpy. Columns whose name contains 'time' are left out;
header cards whose key contains TIME, DATE or VERS are left out, and RUNFP (a hash that includes the
program version) is reported but never fails a case.

  compare_rows.py table CASE MODE REF NEW [--note TEXT] --results R.tsv
        MODE bitwise: every column (time aside), the row count, column names and header equal bit for bit.
        MODE nf:      noise-free survey rows: every object |e1_new - e1_ref|, |e2_new - e2_ref| <= 1e-7 and the
                      same status (ids bitwise).
        MODE noisy:   >= 99.9 % of objects with |de_i| <= 0.01 * e_i_err (ref's sigma_e) and the same status.
        Tolerance modes say BITWISE when the tables are identical.
  compare_rows.py files CASE REF_DIR NEW_DIR --results R.tsv      every file byte for byte (simulated inputs)
  compare_rows.py record CASE VERDICT DETAIL [--rows N] --results R.tsv   a case that produced no table
  compare_rows.py python OUT_DIR GRID.fits       the Python API case (run with PYTHONPATH=BUILD/python)
  compare_rows.py report R.tsv                   the result table; exit status 1 when any case failed
"""
import argparse
import math
import os
import re
import sys

import numpy as np

PASSING = ("BITWISE", "PASS")
NF_TOL = 1e-7
NOISY_SIGMA_FRACTION = 0.01
NOISY_MIN_FRACTION = 0.999
IGNORED_KEY = re.compile(r"TIME|DATE|VERS", re.IGNORECASE)
INFO_KEYS = {"RUNFP"}
DETAIL_MAX = 170


def is_time_column(name):
    return "time" in name.lower()


def append_result(path, case, rows, verdict, detail):
    detail = " ".join(str(detail).split())  # one line, no tabs
    if len(detail) > DETAIL_MAX:
        detail = detail[: DETAIL_MAX - 3] + "..."
    with open(path, "a") as f:
        f.write(f"{case}\t{rows}\t{verdict}\t{detail}\n")


# ---------------------------------------------------------------- reading tables

class Table:
    """Columns (name -> 1-D array, in file order), header cards per HDU, an HDU summary."""

    def __init__(self, path):
        self.path = path
        self.columns = {}
        self.headers = []  # per HDU: list of (key, value, comment)
        self.layout = []  # per HDU: (name, kind, rows, columns)
        if path.endswith(".npy"):
            a = np.load(path, allow_pickle=False)
            if a.dtype.names is None:
                raise ValueError(f"{path}: not a structured array")
            self.rows = len(a)
            for n in a.dtype.names:
                self.columns[n] = np.ascontiguousarray(a[n])
            self.layout = [("npy", "structured array", self.rows, list(a.dtype.names))]
            return
        import stampede

        hdus = stampede.fits_hdus(path)
        table = None
        for h in hdus:
            self.layout.append((h["name"], h["kind"], h["rows"], list(h["columns"])))
            self.headers.append(stampede.fits_header(path, h["index"]))
            if table is None and h["kind"] == "table":
                table = h
        if table is None:
            raise ValueError(f"{path}: no table HDU")
        self.table_hdu = table["name"] or table["index"]
        self.rows = table["rows"]
        names = list(table["columns"])
        data = stampede.read_table(path, table["index"], names) if names else {}
        for n in names:
            self.columns[n] = np.asarray(data[n])

    def names(self):
        return list(self.columns)


def bits(a):
    """An array's values as integers of its width, for a bitwise comparison (NaN payloads included)."""
    a = np.ascontiguousarray(a)
    if a.dtype.kind == "f":
        return a.view(np.uint64 if a.itemsize == 8 else np.uint32)
    if a.dtype.kind in "iub":
        return a.astype(np.int64)
    return a.view(np.uint8).reshape(len(a), -1)


def differing_rows(x, y):
    bx, by = bits(x), bits(y)
    d = bx != by
    return d if d.ndim == 1 else d.any(axis=1)


def max_abs_diff(x, y, mask):
    if not mask.any():
        return 0.0
    if x.dtype.kind not in "fiu" or y.dtype.kind not in "fiu":
        return float("nan")
    dx = np.abs(x[mask].astype(np.float64) - y[mask].astype(np.float64))
    dx = dx[np.isfinite(dx)]
    return float(dx.max()) if dx.size else float("inf")  # inf: a NaN/inf on one side only


def header_differences(ref, new):
    """(failing differences, informational notes) between the two files' headers."""
    fails, notes = [], []
    for i, (hr, hn) in enumerate(zip(ref.headers, new.headers)):
        def kept(cards):
            return [(k, repr(v), c) for k, v, c in cards if not IGNORED_KEY.search(k)]

        for key in INFO_KEYS:
            vr = [v for k, v, _ in hr if k == key]
            vn = [v for k, v, _ in hn if k == key]
            if vr != vn:
                notes.append(f"{key} differs (ignored)")
        cr = [c for c in kept(hr) if c[0] not in INFO_KEYS]
        cn = [c for c in kept(hn) if c[0] not in INFO_KEYS]
        if cr == cn:
            continue
        kr = {c[0]: c for c in cr}
        kn = {c[0]: c for c in cn}
        only_r = [k for k in kr if k not in kn]
        only_n = [k for k in kn if k not in kr]
        changed = [k for k in kr if k in kn and kr[k][1] != kn[k][1]]
        parts = []
        if only_r:
            parts.append("missing " + ",".join(only_r[:4]))
        if only_n:
            parts.append("extra " + ",".join(only_n[:4]))
        for k in changed[:3]:
            parts.append(f"{k} {kr[k][1]}->{kn[k][1]}")
        if not parts:
            parts.append("card order or comments differ")
        fails.append(f"HDU {i} header: " + "; ".join(parts))
    return fails, notes


def structure_differences(ref, new):
    """Row count, column names (time columns included: a renamed or dropped one is a change) and HDUs."""
    fails = []
    if ref.rows != new.rows:
        fails.append(f"rows {ref.rows} vs {new.rows}")
    rn, nn = ref.names(), new.names()
    if rn != nn:
        missing = [c for c in rn if c not in nn]
        extra = [c for c in nn if c not in rn]
        if missing or extra:
            fails.append("columns: " + (f"missing {','.join(missing[:5])} " if missing else "")
                         + (f"extra {','.join(extra[:5])}" if extra else ""))
        else:
            fails.append("column order differs")
    lr = [(n, k, r) for n, k, r, _ in ref.layout]
    ln = [(n, k, r) for n, k, r, _ in new.layout]
    if lr != ln and ref.rows == new.rows:
        fails.append(f"HDUs {lr} vs {ln}")
    for n in rn:
        if n in new.columns and ref.columns[n].dtype != new.columns[n].dtype:
            fails.append(f"{n} type {ref.columns[n].dtype} vs {new.columns[n].dtype}")
    return fails


def column_report(ref, new, cols):
    """Per column that differs: (name, rows differing, max |diff|), worst first."""
    out = []
    for c in cols:
        x, y = ref.columns[c], new.columns[c]
        d = differing_rows(x, y)
        if d.any():
            out.append((c, int(d.sum()), max_abs_diff(x, y, d)))
    out.sort(key=lambda t: (-(t[2] if not math.isnan(t[2]) else math.inf), -t[1]))
    return out


def fmt(v):
    if isinstance(v, float):
        if math.isnan(v) or math.isinf(v):
            return str(v)
        return f"{v:.2g}"
    return str(v)


def compare_tables(case, mode, ref_path, new_path, note):
    ref, new = Table(ref_path), Table(new_path)
    rows = str(ref.rows) if ref.rows == new.rows else f"{ref.rows}/{new.rows}"
    fails = structure_differences(ref, new)
    hfails, notes = header_differences(ref, new) if ref.headers and new.headers else ([], [])
    if note:
        notes.insert(0, note)
    if fails:  # rows or columns differ: nothing row by row to compare
        return rows, "FAIL", "; ".join(fails + hfails + notes)
    cols = [c for c in ref.names() if not is_time_column(c) and c in new.columns]
    diffs = column_report(ref, new, cols)
    if not diffs and not hfails:
        return rows, "BITWISE", "; ".join(notes) or "-"
    if mode == "bitwise":
        parts = []
        if diffs:
            worst = ", ".join(f"{c} {n} rows max {fmt(m)}" for c, n, m in diffs[:3])
            more = f" (+{len(diffs) - 3} cols)" if len(diffs) > 3 else ""
            parts.append(f"{len(diffs)} cols differ: {worst}{more}")
        return rows, "FAIL", "; ".join(parts + hfails + notes)

    # Tolerance modes (survey rows).
    need = ["e1", "e2", "status"] + (["e1_err", "e2_err"] if mode == "noisy" else [])
    absent = [c for c in need if c not in ref.columns]
    if absent:
        return rows, "FAIL", f"no column {','.join(absent)} for mode {mode}"
    parts = []
    ok = True
    id_cols = [c for c in ("id", "number") if c in ref.columns]
    for c in id_cols:
        if differing_rows(ref.columns[c], new.columns[c]).any():
            ok = False
            parts.append(f"{c} differs")
    same_status = ref.columns["status"] == new.columns["status"]
    n_status = int((~same_status).sum())
    de = []
    for c in ("e1", "e2"):
        x, y = ref.columns[c].astype(np.float64), new.columns[c].astype(np.float64)
        same_bits = ~differing_rows(ref.columns[c], new.columns[c])
        d = np.where(same_bits, 0.0, np.abs(y - x))
        d = np.where(np.isnan(d), np.inf, d)  # NaN on one side only
        de.append(d)
    de_max = float(max(d.max() for d in de)) if ref.rows else 0.0
    if mode == "nf":
        bad = (de[0] > NF_TOL) | (de[1] > NF_TOL) | ~same_status
        if bad.any():
            ok = False
        parts.append(f"max|de| {fmt(de_max)} (<= {NF_TOL:g}: {ref.rows - int(((de[0] > NF_TOL) | (de[1] > NF_TOL)).sum())}"
                     f"/{ref.rows})")
    else:
        ratio = []
        for d, c in zip(de, ("e1_err", "e2_err")):
            s = ref.columns[c].astype(np.float64)
            r = np.where(d == 0.0, 0.0, d / np.where(np.isfinite(s) & (s > 0), s, np.nan))
            ratio.append(np.where(np.isnan(r), np.inf, r))
        worst_ratio = float(max(r.max() for r in ratio)) if ref.rows else 0.0
        good = (ratio[0] <= NOISY_SIGMA_FRACTION) & (ratio[1] <= NOISY_SIGMA_FRACTION) & same_status
        n_good = int(good.sum())
        if ref.rows and n_good < NOISY_MIN_FRACTION * ref.rows:
            ok = False
        parts.append(f"{n_good}/{ref.rows} within {NOISY_SIGMA_FRACTION:g} sigma_e (need {NOISY_MIN_FRACTION:.1%}); "
                     f"max|de| {fmt(de_max)} = {fmt(worst_ratio)} sigma_e")
    parts.append("status same" if n_status == 0 else f"status differs in {n_status} rows")
    others = [t for t in diffs if t[0] not in ("e1", "e2")]
    if others:
        c, n, m = others[0]
        parts.append(f"worst other: {c} max {fmt(m)} ({len(others)} cols differ)")
    if hfails:
        ok = False
    return rows, "PASS" if ok else "FAIL", "; ".join(parts + hfails + notes)


# ---------------------------------------------------------------- other modes

def compare_files(ref_dir, new_dir):
    def listing(root):
        out = []
        for d, _, files in os.walk(root):
            for f in files:
                out.append(os.path.relpath(os.path.join(d, f), root))
        return sorted(out)

    lr, ln = listing(ref_dir), listing(new_dir)
    if lr != ln:
        only_r = sorted(set(lr) - set(ln))
        only_n = sorted(set(ln) - set(lr))
        return f"{len(lr)}/{len(ln)}", "FAIL", f"files: missing {only_r[:3]} extra {only_n[:3]}"
    differ = []
    for f in lr:
        with open(os.path.join(ref_dir, f), "rb") as a, open(os.path.join(new_dir, f), "rb") as b:
            if a.read() != b.read():
                differ.append(f)
    if differ:
        return str(len(lr)), "FAIL", f"{len(differ)} files differ: {', '.join(differ[:4])}"
    return str(len(lr)), "BITWISE", "byte-identical files"


def run_python(out_dir, grid):
    import warnings

    import stampede

    os.makedirs(out_dir, exist_ok=True)
    hdr = {k: v for k, v, _ in stampede.fits_header(grid, 0)}
    img = stampede.read_image(grid, hdu=0)
    s = int(hdr["STAMPSZ"])
    ny, nx = img.shape[0] // s, img.shape[1] // s
    stamps = np.ascontiguousarray(img.reshape(ny, s, nx, s).transpose(0, 2, 1, 3).reshape(ny * nx, s, s))
    opts = stampede.Options(psf_beta=hdr["PSFBETA"], psf_fwhm=hdr["PSFFWHM"], psf_e1=hdr["PSFE1"],
                            psf_e2=hdr["PSFE2"], noise_sigma=hdr["NOISESIG"])
    np.save(os.path.join(out_dir, "py-fit_stamps.npy"),
            stampede.fit_stamps(stamps, options=opts, threads=2, grid_nx=nx))
    np.save(os.path.join(out_dir, "py-fit_stamps-mc.npy"),
            stampede.fit_stamps(stamps, options=opts.replace(metacal=True), threads=2, grid_nx=nx))
    # A PSF image per stamp (three Gaussians of other widths and shapes in turn) and a weight map
    # that masks each stamp's first row: the per-object PSF cache and the mask weights.
    y, x = np.mgrid[0:25, 0:25] - 12.0
    kinds = []
    for sx, sy, rho in ((1.2, 1.3, 0.05), (1.5, 1.4, -0.1), (1.1, 1.1, 0.0)):
        q = (x / sx) ** 2 + (y / sy) ** 2 - 2 * rho * x * y / (sx * sy)
        g = np.exp(-0.5 * q / (1 - rho * rho))
        kinds.append(g / g.sum())
    psfs = np.ascontiguousarray(np.stack([kinds[i % 3] for i in range(len(stamps))]))
    weights = np.full(stamps.shape, 1.0 / hdr["NOISESIG"] ** 2)
    weights[:, 0, :] = 0
    np.save(os.path.join(out_dir, "py-fit_stamps-psfs.npy"),
            stampede.fit_stamps(stamps, weights=weights, psf=psfs, options=stampede.Options(),
                                threads=2, grid_nx=nx))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the header's NOISESIG taken as noise_sigma
        stampede.run_fit(input=grid, output=os.path.join(out_dir, "py-run_fit.fits"), threads=2, overwrite=True)


def report(path):
    lines = []
    if os.path.exists(path):
        with open(path) as f:
            lines = [ln.rstrip("\n").split("\t") for ln in f if ln.strip()]
    header = ["case", "rows", "verdict", "worst differences"]
    w = [max([len(header[i])] + [len(r[i]) for r in lines]) for i in range(3)]
    print(f"{header[0]:<{w[0]}}  {header[1]:>{w[1]}}  {header[2]:<{w[2]}}  {header[3]}")
    print(f"{'-' * w[0]}  {'-' * w[1]}  {'-' * w[2]}  {'-' * 17}")
    for r in lines:
        print(f"{r[0]:<{w[0]}}  {r[1]:>{w[1]}}  {r[2]:<{w[2]}}  {r[3]}")
    failed = [r[0] for r in lines if r[2] not in PASSING]
    bitwise = sum(r[2] == "BITWISE" for r in lines)
    print(f"{len(lines)} cases: {len(lines) - len(failed)} passed ({bitwise} bitwise), {len(failed)} failed"
          + (f": {', '.join(failed)}" if failed else ""))
    return 1 if failed or not lines else 0


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("table")
    t.add_argument("case")
    t.add_argument("mode", choices=["bitwise", "nf", "noisy"])
    t.add_argument("ref")
    t.add_argument("new")
    t.add_argument("--note", default="")
    t.add_argument("--results", required=True)
    fl = sub.add_parser("files")
    fl.add_argument("case")
    fl.add_argument("ref")
    fl.add_argument("new")
    fl.add_argument("--results", required=True)
    r = sub.add_parser("record")
    r.add_argument("case")
    r.add_argument("verdict")
    r.add_argument("detail")
    r.add_argument("--rows", default="-")
    r.add_argument("--results", required=True)
    py = sub.add_parser("python")
    py.add_argument("out_dir")
    py.add_argument("grid")
    rp = sub.add_parser("report")
    rp.add_argument("results")
    a = p.parse_args()

    if a.cmd == "table":
        try:
            rows, verdict, detail = compare_tables(a.case, a.mode, a.ref, a.new, a.note)
        except Exception as e:  # an unreadable table is a failed case, not a crashed harness
            rows, verdict, detail = "-", "ERROR", f"{type(e).__name__}: {e}"
        append_result(a.results, a.case, rows, verdict, detail)
        return 0 if verdict in PASSING else 1
    if a.cmd == "files":
        rows, verdict, detail = compare_files(a.ref, a.new)
        append_result(a.results, a.case, rows, verdict, detail)
        return 0 if verdict in PASSING else 1
    if a.cmd == "record":
        append_result(a.results, a.case, a.rows, a.verdict, a.detail)
        return 0 if a.verdict in PASSING else 1
    if a.cmd == "python":
        run_python(a.out_dir, a.grid)
        return 0
    return report(a.results)


if __name__ == "__main__":
    sys.exit(main())
