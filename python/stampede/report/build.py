"""build_report: the inputs checked, the tables streamed once through the accumulators, the truth
compared set by set, the figures drawn and the page written into a temporary directory that is
renamed into place only when complete."""

import math
import os
import shutil
import tempfile

import numpy as np

from . import figures
from . import metadetect
from .inputs import ReportError, ResultTable, SavedImages, check_distinct, check_tables, match_truth
from .page import Page, note, number, pre, table
from .shear import METRICS_SET_HEADER, ShearAgainstTruth, metrics_lines, metrics_set_line
from .statistics import BinnedMean, Histogram, Histogram2D, StatusCounts, usable_for_shear

CHUNK_ROWS = 1 << 18  # rows read at a time: bounds memory whatever the table's size
WORST_SHOWN = 8  # objects in the residual mosaic
SKY_CELLS = 48  # per axis
BIAS_BINS = 4  # bins of S/N and of size for m and c


def asinh_histogram(label, **kw):
    # asinh(x) is linear near 0 and logarithmic beyond: one fixed grid serves values from 1e-2 to
    # 1e10 and of either sign, at 0.5 % resolution where it is logarithmic.
    return Histogram(label, -25.0, 25.0, 10000, asinh_scale=1.0, **kw)


class Accumulators:
    """Everything the page shows that is computed from every row, in fixed-size state."""

    def __init__(self, tables, sky_box, image_ids):
        self.counts = StatusCounts()
        self.hist = {
            "e1": Histogram("e1", -1.0, 1.0, 800), "e2": Histogram("e2", -1.0, 1.0, 800),
            "|e|": Histogram("|e|", 0.0, 1.2, 480), "snr": asinh_histogram("S/N (snr)"),
            "radius": asinh_histogram(f"radius [{'arcsec' if tables[0].survey else 'pixel'}]"),
            "flux": asinh_histogram("flux"), "bulge_flux": asinh_histogram("bulge_flux"),
            "disc_flux": asinh_histogram("disc_flux"), "chi2dof": asinh_histogram("χ²/dof"),
            "n_iter": Histogram("iterations (n_iter)", -0.5, 1000.5, 1001, integer=True),
            "time_ms": asinh_histogram("time per object [ms]"),
        }
        self.metacal = all(t.metacal for t in tables)
        if self.metacal:
            for name in ("R11", "R22"):
                self.hist[name] = Histogram(name, -3.0, 5.0, 1600)
        self.leakage = [BinnedMean(-0.5, 0.5, 2000) for _ in (0, 1)]
        self.sky = Histogram2D(sky_box[0], sky_box[1], (SKY_CELLS, SKY_CELLS)) if sky_box else None
        self.image_ids = np.array(image_ids or [], dtype=np.int64)
        self.image_rows = []

    def add(self, table, chunk, dof, images_table):
        c = chunk
        usable = usable_for_shear(c["status"], c["flags"], c["e1"], c["e2"])
        self.counts.add(c["status"], c["flags"], usable, c.get("time_us", np.full(c["e1"].size, np.nan)))
        fitted = np.isin(c["status"], (0, 1))  # statuses with fitted parameters (others are NaN)
        for name in ("e1", "e2", "snr", "radius", "flux", "bulge_flux", "disc_flux"):
            if name in c:  # the fluxes are not required columns (REQUIRED_COLUMNS)
                self.hist[name].add(c[name][fitted])
        self.hist["|e|"].add(np.hypot(c["e1"], c["e2"])[fitted])
        self.hist["chi2dof"].add(c["chi2"][fitted] / dof)
        self.hist["n_iter"].add(c["n_iter"][fitted].astype(np.float64))
        if "time_us" in c:
            self.hist["time_ms"].add(c["time_us"] * 1e-3)
        if self.metacal:
            for name in ("R11", "R22"):
                self.hist[name].add(c[name][usable])
        if "psf_e1" in c and "psf_e2" in c:
            for k in (0, 1):
                self.leakage[k].add(c[f"psf_e{k + 1}"][usable], c[f"e{k + 1}"][usable])
        if self.sky is not None and "ra" in c:
            ra = wrap_ra(c["ra"], self.sky.x_range)
            self.sky.add(ra[usable], c["dec"][usable], e1=c["e1"][usable], e2=c["e2"][usable])
        if table is images_table and self.image_ids.size:
            hit = np.isin(c["id"], self.image_ids)
            for i in np.flatnonzero(hit):
                self.image_rows.append((int(c["id"][i]), float(c["chi2"][i]), float(c["chi2"][i] / dof),
                                        float(c["snr"][i]), int(c["status"][i]), int(c["flags"][i])))


STREAMED = ("id", "e1", "e2", "radius", "snr", "chi2", "n_iter", "status", "flags", "time_us", "flux", "bulge_flux",
            "disc_flux", "psf_e1", "psf_e2", "ra", "dec", "R11", "R22")


def wrap_ra(ra, x_range):
    # A field across ra = 0 is mapped to (-180, 180] so that it is one box.
    return np.where(ra > 180.0, ra - 360.0, ra) if x_range[0] < 0 else ra


def sky_box(tables):
    """(ra range, dec range) of the survey tables' objects, padded; None without survey tables.
    A cheap pass over two columns, so that the map's cells are fixed before the main pass."""
    survey = [t for t in tables if t.survey]
    if not survey:
        return None
    lo = np.array([math.inf, math.inf, math.inf])
    hi = -lo
    for t in survey:
        for _, c in t.chunks(("ra", "dec"), CHUNK_ROWS):
            # Positions on the sky only: a damaged table's ra of 1e308 would make the map's cells infinite.
            on_sky = (np.abs(c["ra"]) <= 360.0) & (np.abs(c["dec"]) <= 90.0)
            ra, dec = c["ra"][on_sky], c["dec"][on_sky]
            if ra.size:
                shifted = np.where(ra > 180.0, ra - 360.0, ra)
                lo = np.minimum(lo, [ra.min(), shifted.min(), dec.min()])
                hi = np.maximum(hi, [ra.max(), shifted.max(), dec.max()])
    if not np.isfinite(lo).all():
        return None
    ra_lo, ra_hi = (lo[1], hi[1]) if hi[0] - lo[0] > hi[1] - lo[1] else (lo[0], hi[0])
    # A field that is a line or a point (a simulation's) gets a box at least a tenth as wide as
    # it is long, and an arcminute: cells of a sensible area.
    span = max(ra_hi - ra_lo, hi[2] - lo[2], 1.0 / 60)
    pad_ra = 0.02 * span + max(0.0, 0.1 * span - (ra_hi - ra_lo)) / 2
    pad_dec = 0.02 * span + max(0.0, 0.1 * span - (hi[2] - lo[2])) / 2
    return (ra_lo - pad_ra, ra_hi + pad_ra), (lo[2] - pad_dec, hi[2] + pad_dec)


def quantile_edges(hist, bins):
    """Bin edges at equal-population quantiles of a Histogram; outer edges open (±inf)."""
    inner = sorted({hist.quantile(q) for q in np.arange(1, bins) / bins})
    return np.array([-math.inf, *inner, math.inf])


def bin_labels(edges, hist):
    lo, hi = hist.quantile(0.0), hist.quantile(1.0)
    finite = [lo, *edges[1:-1], hi]
    return [f"{finite[i]:.3g} – {finite[i + 1]:.3g}" for i in range(len(edges) - 1)], \
        [math.sqrt(max(1e-12, finite[i]) * max(1e-12, finite[i + 1])) for i in range(len(edges) - 1)]


# The files a report writes: only these are ever replaced or removed in an existing directory.
REPORT_FILES = frozenset({"report.html", "status.png", "distributions.png", "psf_leakage.png", "sky.png",
                          "e_vs_truth.png", "bias_bins.png", "metacal_R.png", "residuals.png", "metadetect_cuts.png",
                          "metadetect_response.png"})


def check_output(out_dir, overwrite):
    """Refuses an output that is not a directory, or that holds anything but a report's own files
    (named, so nothing of the user's is touched), or a report without --overwrite."""
    if os.path.lexists(out_dir) and not os.path.isdir(out_dir):
        raise ReportError(f"-o {out_dir}: exists and is not a directory")
    if not os.path.isdir(out_dir):
        return
    entries = sorted(os.listdir(out_dir))
    foreign = [e for e in entries if e not in REPORT_FILES or not os.path.isfile(os.path.join(out_dir, e))
               or os.path.islink(os.path.join(out_dir, e))]
    if foreign:
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
        raise ReportError(f"-o {out_dir}: the directory holds files that are not a report's ({shown}); a report "
                          "replaces only its own files (report.html and its figures): give an empty or new directory")
    if entries and not overwrite:
        raise ReportError(f"-o {out_dir}: the directory holds a report (--overwrite replaces it)")


def install(tmp, out_dir):
    """Puts the finished report in place. A new directory is renamed into place whole (a reader
    sees no report or all of it). In an existing directory (holding at most an earlier report, see
    check_output) each file is renamed over its old version, the figures first and the page last,
    then the old report's figures the new one does not have are removed: nothing else in the
    directory is touched, and the directory itself (its permissions, a symbolic link to it, `-o .`)
    stays."""
    if not os.path.isdir(out_dir):
        os.rename(tmp, out_dir)
        return
    new = sorted(os.listdir(tmp), key=lambda name: name == "report.html")
    for name in new:
        os.replace(os.path.join(tmp, name), os.path.join(out_dir, name))
    for name in REPORT_FILES.difference(new):
        path = os.path.join(out_dir, name)
        if os.path.isfile(path) and not os.path.islink(path):
            os.remove(path)
    os.rmdir(tmp)


def build_report(table_paths, out_dir, truth=None, images=None, overwrite=False, progress=None, shear=None):
    """Writes out_dir/report.html (and its PNGs) for the result tables, or for `stampede metadetect`
    tables (recognised by their METADETECT HDU: one table, or a shear pair +g then -g, whose true
    shear is `shear` (g1, g2) or the +g table's first input's G1, G2); returns the page's path.
    Raises ReportError for bad inputs, leaving no report behind."""
    if not table_paths:
        raise ReportError("give at least one result table")
    out_dir = os.path.normpath(str(out_dir))
    check_output(out_dir, overwrite)
    table_paths = [str(p) for p in table_paths]
    kinds = [metadetect.is_metadetect(p) for p in table_paths]
    if any(kinds):
        if not all(kinds):
            raise ReportError(f"{table_paths[kinds.index(True)]} is a `stampede metadetect` table but "
                              f"{table_paths[kinds.index(False)]} is not: report them separately")
        if truth or images:
            raise ReportError("--truth and --images are for `stampede fit` tables: a metadetect shear pair's true "
                              "shear is its first input's G1, G2 keys, or --shear")
        inputs = metadetect.MetadetectInputs(table_paths, shear)
        check_distinct(inputs.tables)
        if shear is not None and len(inputs.tables) != 2:
            raise ReportError("--shear is the true shear of a metadetect shear pair: give the +g table and the -g one")

        def write(tmp):
            page, _ = metadetect.write_page(inputs, tmp, CHUNK_ROWS, progress)
            with open(os.path.join(tmp, "report.html"), "w", encoding="utf-8") as f:
                f.write(page.html())
    else:
        if shear is not None:
            raise ReportError("--shear is the true shear of a metadetect shear pair; the tables given are `stampede "
                              "fit` tables (their truth: --truth)")
        tables = check_tables([ResultTable(p) for p in table_paths])
        truths = match_truth(tables, str(truth)) if truth else None
        saved = SavedImages(images, tables) if images else None

        def write(tmp):
            write_report(tables, truths, saved, tmp, progress)
    # The temporary lies beside the new directory, or inside the existing one: the same filesystem
    # as the report's files either way, so every rename is atomic.
    existing = os.path.isdir(out_dir)
    parent = out_dir if existing else os.path.dirname(os.path.abspath(out_dir))
    os.makedirs(parent, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=".report-", dir=parent)
    try:
        write(tmp)
        os.chmod(tmp, 0o755)
        install(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return os.path.join(out_dir, "report.html")


def write_report(tables, truths, saved, out, progress):
    acc = Accumulators(tables, sky_box(tables), saved.ids if saved else None)
    free = tables[0].free_parameters()
    for t in tables:
        pixels = t.pixels_per_object()
        dof = (pixels - t.free_parameters()) if pixels else 1.0
        for start, chunk in t.chunks(STREAMED, CHUNK_ROWS):
            acc.add(t, chunk, dof, saved.table if saved else None)
            if progress:
                progress(t.path, start + chunk["id"].size, t.rows)
    if any(t.pixels_per_object() is None for t in tables):
        acc.hist["chi2dof"].label = "χ² (pixels per object not recorded: survey tables, or no STAMP_SIZE)"
    page = Page(f"stampede report: {', '.join(os.path.basename(t.path) for t in tables)}")
    summary_section(page, tables, acc, out, free)
    histogram_section(page, acc, out)
    leakage_section(page, tables, acc, out)
    if acc.sky is not None:
        sky_section(page, acc, out)
    if truths:
        truth_section(page, tables, truths, acc, out)
    if saved:
        mosaic_section(page, saved, acc, out)
    with open(os.path.join(out, "report.html"), "w", encoding="utf-8") as f:
        f.write(page.html())


def summary_section(page, tables, acc, out, free):
    names, meanings = {}, {}
    for t in tables:
        names.update(t.status_names())
        meanings.update(t.flag_meanings())
    c = acc.counts
    status_rows = [(f"{s} {names.get(s, '?')}", n, f"{100 * n / c.rows:.2f} %") for s, n in sorted(c.status.items())]
    flag_rows = [(f"{1 << b} (bit {b})", meanings.get(b, "?"), int(n), f"{100 * n / c.rows:.2f} %")
                 for b, n in enumerate(c.flag_bits) if n]
    time = acc.hist["time_ms"]
    overview = [("tables", len(tables)), ("objects", c.rows),
                ("usable for shear", f"{c.usable} ({100 * c.usable / c.rows:.2f} %)"),
                ("input", ", ".join(sorted({t.positions for t in tables}))),
                ("metacal", "yes" if acc.metacal else "no"),
                ("time per object, mean", f"{number(time.mean())} ms"),
                ("time per object, median", f"{number(time.quantile(0.5))} ms"),
                ("fit time, total (CPU)", f"{number(c.time_sum * 1e-6)} s")]
    figures.status_bars([r[0] for r in status_rows], [r[1] for r in status_rows], os.path.join(out, "status.png"))
    inputs = [(os.path.basename(t.path), t.rows, t.positions, *(str(t.header.get(k, "")) for k in
                                                                 ("INPUT", "INSETID", "RUNFP"))) for t in tables]
    digests = [(os.path.basename(t.path), k, str(v)) for t in tables for k, v in t.identity()
               if k not in ("INPUT", "INSETID", "RUNFP")]
    options = tables[0].options()
    differing = sorted({k for t in tables[1:] for k, v in t.options() if dict(options).get(k) != v})
    below = [table(inputs, ["table", "rows", "positions", "INPUT", "INSETID", "RUNFP"], text_columns=(0, 2, 3, 4, 5)),
             table(digests, ["table", "key", "value"], text_columns=(0, 1, 2)) if digests else "",
             "<details><summary>options of the run" + (f" (first table; differing in others: {', '.join(differing)})"
                                                       if differing else "") + "</summary>" +
             table([(k, str(v)) for k, v in options], ["option", "value"], text_columns=(0, 1)) + "</details>",
             note(f"Usable for shear: status ok and none of the flags 4/16/32/65536/131072/262144/524288/1048576, "
                  f"e finite (as `stampede metrics`). χ²/dof uses stamp pixels minus the {free} free parameters.")]
    page.section("Run summary", "status.png",
                 [table(overview, ["", ""], text_columns=(0, 1)), table(status_rows, ["status", "objects", "share"]),
                  table(flag_rows, ["flag", "meaning", "objects", "share"], text_columns=(0, 1)) if flag_rows
                  else note("No flags set.")], below)


def histogram_section(page, acc, out):
    keys = ["e1", "e2", "|e|", "snr", "radius", "flux", "bulge_flux", "disc_flux", "chi2dof", "n_iter"]
    hists = [acc.hist[k] for k in keys]
    figures.histograms(hists, os.path.join(out, "distributions.png"))
    stats = ["objects", "not finite", "mean", "std", "min", "5%", "median", "95%", "max"]
    rows = [(h.label, *(h.summary()[s] for s in stats)) for h in hists]
    page.section("Distributions", "distributions.png", [],
                 [table(rows, ["quantity", *stats]),
                  note("Rows with fitted parameters (status ok or max_iterations). Plotted: the central 99 %; "
                       "the table's quantiles are exact to a fine bin (0.5 % or 0.0025 in e).")])


def leakage_section(page, tables, acc, out):
    lines = [acc.leakage[k].line() for k in (0, 1)]
    binned = [acc.leakage[k].display() for k in (0, 1)]
    figures.leakage(binned, lines, ("e1", "e2"), os.path.join(out, "psf_leakage.png"))
    fit_rows = [(f"e{k + 1}", lines[k]["n"], lines[k]["alpha"], lines[k]["alpha_err"], lines[k]["intercept"],
                 lines[k]["intercept_err"], lines[k]["x_spread"]) for k in (0, 1)]
    bins = [(f"e{k + 1}", *row) for k in (0, 1) for row in binned[k]]
    page.section("PSF leakage: ⟨e⟩ against the PSF's e", "psf_leakage.png",
                 [table(fit_rows, ["component", "objects", "α", "σ(α)", "intercept", "σ", "rms PSF e"]),
                  table(bins, ["component", "PSF e (mean)", "⟨e⟩", "σ", "objects"])],
                 [note("Least-squares line e_i = c + α e_i(PSF) over every usable object (errors as for independent "
                       "objects); bins of about equal population. A table with one PSF has no α: fit several "
                       "PSFs (survey tables, or sets of different PSF e) to measure it.")])


def sky_section(page, acc, out):
    figures.sky_maps(acc.sky, os.path.join(out, "sky.png"))
    filled = acc.sky.counts > 0
    rows = [("ra range [deg]", f"{acc.sky.x_range[0]:.4f} – {acc.sky.x_range[1]:.4f}"),
            ("dec range [deg]", f"{acc.sky.y_range[0]:.4f} – {acc.sky.y_range[1]:.4f}"),
            ("cells", f"{SKY_CELLS} x {SKY_CELLS} ({int(filled.sum())} with objects)"),
            ("usable objects mapped", int(acc.sky.counts.sum())),
            ("rms of cell ⟨e1⟩", float(np.nanstd(acc.sky.mean("e1")[filled]))),
            ("rms of cell ⟨e2⟩", float(np.nanstd(acc.sky.mean("e2")[filled])))]
    page.section("Sky maps: density and ⟨e⟩", "sky.png", [table(rows, ["", ""], text_columns=(0, 1))])


def bias_rows(labels, metrics):
    return [(label, *(m[k] if m else math.nan for k in ("m1", "m1_err", "c1", "c1_err", "m2", "m2_err", "c2",
                                                        "c2_err"))) for label, m in zip(labels, metrics)]


def truth_section(page, tables, truths, acc, out):
    snr_edges = quantile_edges(acc.hist["snr"], BIAS_BINS)
    size_edges = quantile_edges(acc.hist["radius"], BIAS_BINS)
    s = ShearAgainstTruth(tables, truths, snr_edges, size_edges)
    lines = [METRICS_SET_HEADER] + [metrics_set_line(k, x) for k, x in enumerate(s.sets)]
    if s.metrics:
        lines += metrics_lines(s.metrics, s.psf_e)
    else:
        lines.append("m, c: need at least two sets with different shears")
    sets = [(k, os.path.basename(x["fit"]), os.path.basename(x["truth"])) for k, x in enumerate(s.sets)]
    figures.e_against_truth(s.e_vs_true, s.e_vs_true_mean, os.path.join(out, "e_vs_truth.png"))
    page.section("Shear biases against the truth: stampede metrics", None,
                 [pre(lines), table(sets, ["set", "fit", "truth"], text_columns=(1, 2))] + [note(r) for r in s.refused],
                 [note("The numbers `stampede metrics --fit T1 --truth TRUTH1 --fit T2 ...` prints for the tables in "
                       "the order given (bootstrap 200 over ring pairs, seed 1), computed by the same code "
                       "(stampede.set_shear, stampede.shear_metrics).")])
    res = [(f"e{c + 1}", *row) for c in (0, 1) for row in s.e_vs_true_mean[c].display(bins=8, min_count=2)]
    page.section("e against e_true", "e_vs_truth.png",
                 [table(res, ["component", "e_true (mean)", "⟨e⟩", "σ", "objects"])],
                 [note("Usable objects; e_true is the truth's e_obs (the intrinsic shape, sheared). Grey: object "
                       "density (log); points: mean fitted e in bins of e_true.")])
    snr_labels, snr_centres = bin_labels(snr_edges, acc.hist["snr"])
    size_labels, size_centres = bin_labels(size_edges, acc.hist["radius"])
    figures.binned_biases([("S/N (pair mean)", snr_centres, s.snr_metrics),
                           ("radius (pair mean)", size_centres, s.size_metrics)], os.path.join(out, "bias_bins.png"))
    header = ["bin", "m1", "σ", "c1", "σ", "m2", "σ", "c2", "σ"]
    page.section("m and c in bins of S/N and of size", "bias_bins.png",
                 [table(bias_rows(snr_labels, s.snr_metrics), ["S/N"] + header[1:], digits=3),
                  table(bias_rows(size_labels, s.size_metrics), ["radius"] + header[1:], digits=3)],
                 [note("Bins of equal population in the ring pair's mean fitted S/N and radius (both members of a pair "
                       "in one bin, so the ring still cancels the intrinsic shape); per bin, the set estimates and line "
                       "fit of `stampede metrics` over the usable objects in the bin, errors from its bootstrap over "
                       "pairs.")])
    if acc.metacal:
        metacal_section(page, s, acc, out)


def metacal_section(page, s, acc, out):
    figures.histograms([acc.hist["R11"], acc.hist["R22"]], os.path.join(out, "metacal_R.png"), columns=2)
    lines = [METRICS_SET_HEADER] + [metrics_set_line(k, x) for k, x in enumerate(s.metacal_sets)]
    lines += metrics_lines(s.metacal_metrics, s.psf_e) if s.metacal_metrics else ["m, c: need at least two sets"]
    r_rows = [(k, *x["R"]) for k, x in enumerate(s.metacal_sets)]
    stats = ["objects", "mean", "std", "5%", "median", "95%"]
    page.section("Metacalibration: R and the calibrated m, c", "metacal_R.png",
                 [table([(h.label, *(h.summary()[k] for k in stats)) for h in (acc.hist["R11"], acc.hist["R22"])],
                        ["", *stats]),
                  table(r_rows, ["set", "⟨R11⟩", "⟨R12⟩", "⟨R21⟩", "⟨R22⟩"])],
                 [pre(lines), note("Per set g = ⟨R⟩⁻¹⟨e⟩ over usable ring pairs, as `stampede metrics --metacal` "
                                   "without cuts (so no selection response), with its bootstrap; line fit by "
                                   "stampede.shear_metrics.")])


def mosaic_section(page, saved, acc, out):
    rows = sorted(acc.image_rows, key=lambda r: -r[1] if math.isfinite(r[1]) else math.inf)[:WORST_SHOWN]
    if not rows:
        raise ReportError(f"{saved.path}: none of its objects ({len(saved.ids)}) is in {saved.table.path}")
    stamps = [(f"id {r[0]}", saved.images(r[0])) for r in rows]
    figures.mosaic(stamps, os.path.join(out, "residuals.png"))
    page.section("Data, model and residual: the worst χ² of the saved objects", "residuals.png",
                 [table(rows, ["id", "χ²", "χ²/dof", "S/N", "status", "flags"])],
                 [note(f"{len(saved.ids)} objects saved in {os.path.basename(saved.path)} (save_images); shown: the "
                       f"{len(rows)} with the largest χ². To see a run's worst objects, refit with save_images = "
                       "their ids.")])
