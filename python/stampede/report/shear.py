"""Shear biases against a simulation's truth: per set the shear estimate of `stampede metrics`
(stampede.set_shear, ring pairs first, bootstrap over pairs with its seeds) and across sets its line
fit g_est = (1 + m) g + c (stampede.shear_metrics), overall and in bins of S/N and of size; the
metacal form g = <R>^-1 <e> (stampede.metacal_set_shear); e against e_true. Numbers are formatted as `stampede metrics` prints
them, so the page and its output can be compared as text.

Memory: one set's columns at a time (a simulated set is one table), as `stampede metrics` holds."""

import math

import numpy as np

import stampede

from .inputs import ReportError
from .statistics import BinnedMean, Histogram2D, usable_for_shear

BOOTSTRAP = 200  # `stampede metrics` defaults: --bootstrap 200, --seed 1 (set k: seed 1 + k)
SEED = 1
FIT_COLUMNS = ("id", "e1", "e2", "status", "flags", "snr", "radius", "psf_e1", "psf_e2")
METACAL_COLUMNS = ("R11", "R12", "R21", "R22")


def error_text(v, spec, width=0):
    """An error as `stampede metrics` prints it: 'n/a' (right-aligned in `width`) when it could not
    be computed (NaN: fewer than two ring pairs, or a line through two sets without errors)."""
    return format(v, spec) if math.isfinite(v) else f"{'n/a':>{width}s}"


def metrics_set_line(k, s):
    return (f"{k:<4d} {s['g1_true']:+10.6f} {s['g1']:+10.6f} {s['g1'] - s['g1_true']:+10.2e} "
            f"{error_text(s['err1'], '9.2e', 9)} {s['g2_true']:+10.6f} {s['g2']:+10.6f} "
            f"{error_text(s['err2'], '9.2e', 9)} {s['used']:6d} {s['excluded']:8d}")


METRICS_SET_HEADER = (f"{'set':<4s} {'g1_true':>10s} {'g1':>10s} {'g1-g1_t':>10s} {'err1':>9s} {'g2_true':>10s} "
                      f"{'g2':>10s} {'err2':>9s} {'used':>6s} {'excluded':>8s}")


def metrics_lines(m, psf_e):
    """The lines `stampede metrics` prints for m, c and the PSF frame (printf %+.3e, %.1e)."""
    return [f"m{c} = {m[f'm{c}']:+.3e} +- {error_text(m[f'm{c}_err'], '.1e')}   "
            f"c{c} = {m[f'c{c}']:+.3e} +- {error_text(m[f'c{c}_err'], '.1e')}" for c in (1, 2)] + [
            f"PSF frame (e = {psf_e[0]:.3f}, {psf_e[1]:.3f}): c+ = {m['c_plus']:+.3e}  cx = {m['c_cross']:+.3e}",
            f"Q = {m['q']:.1f}  (1e-4 / mean over sets and components of (g_est - g_true)^2)"]



def units_of(pair):
    """Ring-pair labels as unit indices 0..U-1 in order of first appearance (a negative pair: a
    unit of its own), as engine/analysis/unit_shear_estimator.hpp numbers them."""
    labels = np.where(pair < 0, -1 - np.arange(pair.size), pair)
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return rank[inverse], order.size


def pair_means(values, pair):
    """Each row's ring-pair mean of `values`, so both members of a pair fall in the same bin."""
    unit, n_units = units_of(pair)
    finite = np.isfinite(values)
    total = np.bincount(unit, weights=np.where(finite, values, 0.0), minlength=n_units)
    count = np.bincount(unit, weights=finite, minlength=n_units)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (total / count)[unit]


def fit_line(sets, psf_e):
    good = [s for s in sets if s["used"] > 0 and math.isfinite(s["g1"])]
    if len(good) < 2:
        return None
    m = stampede.shear_metrics(good, *psf_e)
    # Sets of one true shear (two fits of one set) define no line: m and c NaN, the page says so as
    # `stampede metrics` does.
    return m if math.isfinite(m["m1"]) and math.isfinite(m["m2"]) else None


class ShearAgainstTruth:
    """Per-set estimates, the cross-set m and c, binned m and c, e against e_true."""

    def __init__(self, tables, truths, snr_edges, size_edges):
        self.snr_edges, self.size_edges = snr_edges, size_edges
        self.sets, self.metacal_sets = [], []
        self.snr_sets = [[] for _ in range(len(snr_edges) - 1)]
        self.size_sets = [[] for _ in range(len(size_edges) - 1)]
        self.e_vs_true = [Histogram2D((-1, 1), (-1, 1), (100, 100)) for _ in (0, 1)]
        self.e_vs_true_mean = [BinnedMean(-1, 1, 200) for _ in (0, 1)]
        self.psf_e = (0.0, 0.0)
        self.refused = []
        self.metacal = all(t.metacal for t in tables)
        for k, (table, truth) in enumerate(zip(tables, truths)):
            self._add_set(k, table, truth)
        self.metrics = fit_line(self.sets, self.psf_e)
        self.snr_metrics = [fit_line(s, self.psf_e) for s in self.snr_sets]
        self.size_metrics = [fit_line(s, self.psf_e) for s in self.size_sets]
        self.metacal_metrics = fit_line(self.metacal_sets, self.psf_e) if self.metacal else None

    def _add_set(self, k, table, truth):
        fit = table.read(FIT_COLUMNS + (METACAL_COLUMNS if table.metacal else ()))
        true = truth.read(("index", "pair", "e1_obs", "e2_obs"))
        if not np.array_equal(fit["id"], true["index"]):
            row = int(np.argmax(fit["id"] != true["index"]))
            raise ReportError(f"{table.table.where}: row {row} is object {fit['id'][row]} but the truth row "
                              f"({truth.table.where}) is object {true['index'][row]}: not the truth of this fit")
        pair = true["pair"] if "pair" in true else np.arange(table.rows)
        usable = usable_for_shear(fit["status"], fit["flags"], fit["e1"], fit["e2"])
        if "psf_e1" in fit and "psf_e2" in fit and abs(fit["psf_e1"][0]) < 1 and abs(fit["psf_e2"][0]) < 1:
            self.psf_e = (float(fit["psf_e1"][0]), float(fit["psf_e2"][0]))  # as metrics: the last set's
        shear = stampede.set_shear(fit["e1"], fit["e2"], usable.astype(np.int32), pair, truth.g1, truth.g2,
                                   bootstrap=BOOTSTRAP, seed=SEED + k)
        shear["fit"], shear["truth"] = table.path, truth.path
        if shear["used"] == 0:
            self.refused.append(f"{table.path}: all {table.rows} rows are excluded (status not ok, excluding flags or "
                                "e not finite), so the set has no shear estimate (stampede metrics refuses it)")
        self.sets.append(shear)
        for edges, out, column in ((self.snr_edges, self.snr_sets, "snr"), (self.size_edges, self.size_sets, "radius")):
            value = pair_means(fit[column], pair)
            for b in range(len(edges) - 1):
                inside = usable & (value >= edges[b]) & (value < edges[b + 1])
                if inside.any():
                    out[b].append(stampede.set_shear(fit["e1"], fit["e2"], inside.astype(np.int32), pair, truth.g1,
                                                     truth.g2, bootstrap=BOOTSTRAP, seed=SEED + k))
        for c in (0, 1):
            if f"e{c + 1}_obs" not in true:  # a truth without the sheared shapes: no e against e_true
                continue
            e, e_true = fit[f"e{c + 1}"][usable], true[f"e{c + 1}_obs"][usable]
            self.e_vs_true[c].add(e_true, e)
            self.e_vs_true_mean[c].add(e_true, e)
        if self.metacal and table.metacal:
            # Without cuts every usable object is selected on all five images (so R_S = 0).
            selected = np.where(usable, 0x1F, 0).astype(np.uint8)
            s = stampede.metacal_set_shear(fit["e1"], fit["e2"], *(fit[name] for name in METACAL_COLUMNS), selected,
                                           pair, truth.g1, truth.g2, step=table.metacal_step, bootstrap=BOOTSTRAP,
                                           seed=SEED + k)
            s["fit"] = table.path
            self.metacal_sets.append(s)
