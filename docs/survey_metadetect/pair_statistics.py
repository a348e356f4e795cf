#!/usr/bin/env python3
"""Per-cell sums of a metadetection shear pair's tables, for the reference estimator over many chunks.

  pair_statistics.py extract PLUS.fits MINUS.fits OUT.npz [--cut-mfrac X]
      each cell's kept rows per shear type (flags == 0, snr > 10, T_ratio > 1.2, mfrac <= X; the
      reference test's cuts, each catalogue by its own quantities): their count and sums of e1, e2
  pair_statistics.py combine OUT1.npz OUT2.npz ... [--bootstrap N] [--seed S] [--shear G]
      m1, c2 over every pair of every chunk, two ways, errors by bootstrap over pairs:
      per cell: m = <g1+ - g1-> / 2 / (<R11+ + R11-> / 2) / g - 1, c = <g2+ + g2-> / 2 / (<R22+ +
        R22-> / 2), g and R each cell's from its kept rows' means, averaged over cells (the reference
        package's shear test);
      pooled: the same with every kept row of every cell in one mean per side and type (`stampede
        metrics --metadetect --estimator package`: each object counts once, as in a survey's mean).
      --versus B1.npz ...: the same pairs under other cuts (chunk for chunk): both, and their
        difference with the same bootstrap draws (the pairs' shared noise cancels in it).
"""
import argparse
import sys

import numpy as np

import stampede

TYPES = ["noshear", "1p", "1m", "2p", "2m"]
STEP = 0.01


def extract(path, cut_mfrac):
    t = stampede.read_table(path, "METADETECT", ["cell", "shear_type", "flags", "snr", "T_ratio", "mfrac", "e1", "e2"])
    ncell = int(t["cell"].max()) + 1
    keep = (t["flags"] == 0) & (t["snr"] > 10) & (t["T_ratio"] > 1.2) & (t["mfrac"] <= cut_mfrac)
    count = np.zeros((ncell, 5))
    s1 = np.zeros((ncell, 5))
    s2 = np.zeros((ncell, 5))
    for k, name in enumerate(TYPES):
        sel = keep & (t["shear_type"] == name)
        cells = t["cell"][sel]
        count[:, k] = np.bincount(cells, minlength=ncell)
        s1[:, k] = np.bincount(cells, weights=t["e1"][sel], minlength=ncell)
        s2[:, k] = np.bincount(cells, weights=t["e2"][sel], minlength=ncell)
    return count, s1, s2


def per_cell(count, s1, s2):
    with np.errstate(invalid="ignore", divide="ignore"):
        e1, e2 = s1 / count, s2 / count
    return e1[:, 0], e2[:, 0], (e1[:, 1] - e1[:, 2]) / (2 * STEP), (e2[:, 3] - e2[:, 4]) / (2 * STEP)


def m_c(p, q, shear):
    """p, q: per-cell (g1, g2, R11, R22) of the two sides."""
    m = np.mean(p[0] - q[0]) / 2 / (np.mean(p[2] + q[2]) / 2) / shear - 1
    c = np.mean(p[1] + q[1]) / 2 / (np.mean(p[3] + q[3]) / 2)
    return m, c, np.mean(p[2] + q[2]) / 2


def m_c_pooled(sp, sq, shear):
    """sp, sq: (count, s1, s2) per cell of the two sides: pooled over the cells."""
    gp = per_cell(*[x.sum(axis=0, keepdims=True) for x in sp])
    gq = per_cell(*[x.sum(axis=0, keepdims=True) for x in sq])
    return m_c([x[0] for x in gp], [x[0] for x in gq], shear)


def report(label, estimate, n, shear, bootstrap, seed):
    m, c, r11 = estimate(np.arange(n))
    rng = np.random.default_rng(seed)
    boot = np.array([estimate(rng.integers(0, n, n))[:2] for _ in range(bootstrap)])
    print(f"  {label:8s} R11 {r11:.5f}  m1 = {m:+.3e} +- {boot[:, 0].std():.1e}   c2 = {c:+.3e} +- {boot[:, 1].std():.1e}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["extract", "combine"])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--cut-mfrac", type=float, default=0.1)
    ap.add_argument("--bootstrap", type=int, default=500)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--shear", type=float, default=0.02)
    ap.add_argument("--versus", nargs="+", default=[])
    a = ap.parse_args()
    if a.mode == "extract":
        plus, minus, out = a.files
        cp, p1, p2 = extract(plus, a.cut_mfrac)
        cm, m1, m2 = extract(minus, a.cut_mfrac)
        np.savez(out, count_plus=cp, s1_plus=p1, s2_plus=p2, count_minus=cm, s1_minus=m1, s2_minus=m2)
        return 0
    keys = ["count", "s1", "s2"]

    def load(files):
        sp = [np.concatenate([np.load(f)[k + "_plus"] for f in files]) for k in keys]
        sq = [np.concatenate([np.load(f)[k + "_minus"] for f in files]) for k in keys]
        return sp, sq, per_cell(*sp), per_cell(*sq)

    sets = [load(a.files)] + ([load(a.versus)] if a.versus else [])
    # A pair with no kept row in some shear type (in any set) has no estimate: left out of all.
    ok = np.all([np.all(np.isfinite(np.array(p + q)), axis=0) for _, _, p, q in sets], axis=0)
    sets = [([x[ok] for x in sp], [x[ok] for x in sq], [x[ok] for x in p], [x[ok] for x in q]) for sp, sq, p, q in sets]
    n = int(ok.sum())
    print(f"pairs {n} (of {len(ok)}; {len(ok) - n} without a kept row in some shear type)")
    estimators = {
        "per cell": lambda s, i: m_c([x[i] for x in s[2]], [x[i] for x in s[3]], a.shear),
        "pooled": lambda s, i: m_c_pooled([x[i] for x in s[0]], [x[i] for x in s[1]], a.shear),
    }
    for label, est in estimators.items():
        if len(sets) == 1:
            report(label, lambda i: est(sets[0], i), n, a.shear, a.bootstrap, a.seed)
            continue
        # m of each set and their difference, with the same draws.
        rng = np.random.default_rng(a.seed)
        full = [est(s, np.arange(n)) for s in sets]
        draws = [rng.integers(0, n, n) for _ in range(a.bootstrap)]
        boot = np.array([[est(s, i)[0] for s in sets] for i in draws])
        print(f"  {label:8s} m1 = {full[0][0]:+.3e} +- {boot[:, 0].std():.1e} versus {full[1][0]:+.3e} +- "
              f"{boot[:, 1].std():.1e}: difference {full[0][0] - full[1][0]:+.3e} +- {(boot[:, 0] - boot[:, 1]).std():.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
