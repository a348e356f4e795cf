#!/usr/bin/env python3
"""Per-galaxy bias of the experiment's catalogues against the simulation truth.

usage: galaxy_bias.py DIRS [DIRS ...]   (DIRS: an S/N directory of run_experiment.sh, or several
                                        joined by commas, pooled: an S/N and its extra batches)

`stampede metrics` measures m from the set means against the sets' shears: with 8 sets whose
shears spread over |g| < 0.05, its error on m is ~1e-2 at S/N 20. The truth files give each
galaxy's sheared ellipticity e_true, whose spread (~0.25) is a far longer lever arm: here the
noise-pair means of e - e_true (objects 4q+r and 4q+r+2 share the galaxy and have opposite noise)
are regressed on e_true per component over all sets,
    e - e_true = c_gal + m_gal e_true,
for the raw e and the calibrated e1_cal, e2_cal. m_gal weights the bias curve differently from the
shear response (for b = a1 e + a3 e^3 along the radius: a1 + a3 <r^4>/<r^2> against
a1 + 2 a3 <r^2> - a3 <r^4>), so it is a precise check of what the calibration removes, not a
replacement for the shear-based m. m_gal = (m_gal,1 + m_gal,2) / 2 with its error from both
components' residuals per noise pair. Rows excluded as in `stampede metrics` (status, flags), with
their noise partner. The regression takes every set as independent: on shear-pair sets, whose two
members repeat the same galaxies and noise, its errors are too small.

Sets simulated as shear pairs (`sim great08 --shear-pairs`: set 2j+1 holds set 2j's galaxies and
noise under -g) also give the shear response itself, per ring-and-noise group (objects 4q..4q+3)
usable in both sets: D = half the difference of the group's mean e in the two sets, S = half the
sum. Per component (1 + m) = sum g D / sum g^2 and c = mean S; the error of m = (m1 + m2) / 2
comes from the groups' residuals of both components together (they share galaxies), not from
adding m1's and m2's errors as if independent.
"""
import glob
import os
import sys

import numpy as np
from astropy.io import fits

EXCLUDING = 4 | 16 | 32 | 65536 | 131072


def load(dirnames, prefix, cols):
    out = {c: [] for c in cols + ["e1_true", "e2_true", "ok"]}
    truths = [t for dirname in dirnames for t in sorted(glob.glob(os.path.join(dirname, "truth_*.fits")))]
    for truth in truths:
        dirname = os.path.dirname(truth)
        k = truth.rsplit("_", 1)[1][:-5]
        path = os.path.join(dirname, f"{prefix}_{k}.fits")
        if not os.path.exists(path):
            continue
        t = fits.open(path)[1].data
        tr = fits.open(truth)[1].data
        ok = (t["status"] == 0) & ((t["flags"].astype(np.int64) & EXCLUDING) == 0)
        for c in cols:
            out[c].append(np.asarray(t[c], float))
        out["e1_true"].append(np.asarray(tr["e1_obs"], float))
        out["e2_true"].append(np.asarray(tr["e2_obs"], float))
        out["ok"].append(ok & np.isfinite(t[cols[0]]) & np.isfinite(t[cols[1]]))
    return {c: np.concatenate(v) for c, v in out.items()} if out["ok"] else None


def regress(d, e1, e2):
    n = len(d["ok"]) // 4 * 4
    rows = []
    for comp, name in ((1, e1), (2, e2)):
        bias = (d[name] - d[f"e{comp}_true"])[:n].reshape(-1, 4)
        truth = d[f"e{comp}_true"][:n].reshape(-1, 4)
        ok = d["ok"][:n].reshape(-1, 4)
        pair_bias = np.concatenate([(bias[:, r] + bias[:, r + 2]) / 2 for r in (0, 1)])
        pair_true = np.concatenate([truth[:, r] for r in (0, 1)])
        pair_ok = np.concatenate([ok[:, r] & ok[:, r + 2] for r in (0, 1)])
        x, y = pair_true[pair_ok], pair_bias[pair_ok]
        a = np.vstack([np.ones_like(x), x]).T
        coef, res, *_ = np.linalg.lstsq(a, y, rcond=None)
        sigma2 = np.sum((y - a @ coef) ** 2) / (len(x) - 2)
        cov = sigma2 * np.linalg.inv(a.T @ a)
        # Each pair's share of the slope's error, kept for the error of (m1 + m2) / 2: the two
        # components' regressions use the same galaxies (pair_ok does not depend on the component).
        influence = (x - x.mean()) * (y - a @ coef) / np.sum((x - x.mean()) ** 2)
        rows.append((coef[1], cov[1, 1] ** 0.5, coef[0], cov[0, 0] ** 0.5, len(x), influence))
    return rows


def mean_slope(rows):
    """m_gal = (m_gal,1 + m_gal,2) / 2 and its error from both components' residuals together."""
    m = 0.5 * (rows[0][0] + rows[1][0])
    return m, np.sum((0.5 * (rows[0][5] + rows[1][5])) ** 2) ** 0.5


def shear_pair_groups(dirnames, prefix, cols):
    """Per usable group of every shear pair: g, half differences and half sums per component."""
    rows = {k: [] for k in ("g1", "g2", "d1", "d2", "s1", "s2")}
    for dirname in dirnames:
        for truth in sorted(glob.glob(os.path.join(dirname, "truth_*.fits"))):
            k = int(truth.rsplit("_", 1)[1][:-5])
            with fits.open(truth) as h:
                if h[0].header.get("SHEARPR", -1) != k + 1 or k % 2:
                    continue
                g = (h[0].header["SHEAR1"], h[0].header["SHEAR2"])
            paths = [os.path.join(dirname, f"{prefix}_{j}.fits") for j in (k, k + 1)]
            if not all(os.path.exists(x) for x in paths):
                continue
            plus, minus = (fits.open(x)[1].data for x in paths)
            n = len(plus) // 4 * 4
            ok = np.ones(n, bool)
            for t in (plus, minus):
                ok &= (t["status"][:n] == 0) & ((t["flags"][:n].astype(np.int64) & EXCLUDING) == 0)
                ok &= np.isfinite(t[cols[0]][:n]) & np.isfinite(t[cols[1]][:n])
            group_ok = ok.reshape(-1, 4).all(axis=1)
            for c, name in enumerate(cols):
                ep = np.asarray(plus[name][:n], float).reshape(-1, 4).mean(axis=1)[group_ok]
                em = np.asarray(minus[name][:n], float).reshape(-1, 4).mean(axis=1)[group_ok]
                rows[f"d{c + 1}"].append(0.5 * (ep - em))
                rows[f"s{c + 1}"].append(0.5 * (ep + em))
                rows[f"g{c + 1}"].append(np.full(group_ok.sum(), g[c]))
    if not rows["g1"]:
        return None
    return {k: np.concatenate(v) for k, v in rows.items()}


def shear_pair_response(d):
    out, residual = [], []
    for c in (1, 2):
        g, dd, ss = d[f"g{c}"], d[f"d{c}"], d[f"s{c}"]
        sgg = np.sum(g * g)
        slope = np.sum(g * dd) / sgg
        residual.append(g * (dd - slope * g) / sgg)  # each group's share of the slope's error
        out.append((slope - 1, np.sum(residual[-1] ** 2) ** 0.5, ss.mean(), ss.std(ddof=1) / len(ss) ** 0.5))
    m = 0.5 * (out[0][0] + out[1][0])
    m_err = np.sum((0.5 * (residual[0] + residual[1])) ** 2) ** 0.5
    return m, m_err, out, len(d["g1"])


def main():
    pair_rows = []
    for arg in sys.argv[1:]:
        dirnames = arg.split(",")
        name = " + ".join(os.path.basename(x.rstrip("/")) for x in dirnames
                          if glob.glob(os.path.join(x, "truth_*.fits")))
        for label, prefix, cols in (("raw e", "fit", ["e1", "e2"]),
                                    ("calibrated (population)", "cal", ["e1_cal", "e2_cal"]),
                                    ("calibrated per object", "obj", ["e1_cal", "e2_cal"]),
                                    ("calibrated (population, table measured at this S/N)", "matched",
                                     ["e1_cal", "e2_cal"])):
            d = shear_pair_groups(dirnames, prefix, cols)
            if d is None:
                continue
            m, m_err, (r1, r2), n = shear_pair_response(d)
            pair_rows.append(f"| {name}, {label} | {m:+.2e} ± {m_err:.1e} | {r1[0]:+.2e} ± {r1[1]:.1e} | "
                             f"{r2[0]:+.2e} ± {r2[1]:.1e} | {r1[2]:+.2e} ± {r1[3]:.1e} | "
                             f"{r2[2]:+.2e} ± {r2[3]:.1e} | {n} |")
    if pair_rows:
        print("Shear pairs, per ring-and-noise group usable in both sets of a pair:")
        print()
        print("| S/N dir, catalogue | m | m1 | m2 | c1 | c2 | groups |")
        print("|---|---|---|---|---|---|---|")
        print("\n".join(pair_rows))
        print()
        print("Per-galaxy regression on e_true:")
        print()
    print("| S/N dir, catalogue | m_gal | m_gal,1 | m_gal,2 | c_gal,1 | c_gal,2 | noise pairs |")
    print("|---|---|---|---|---|---|---|")
    for arg in sys.argv[1:]:
        dirnames = arg.split(",")
        name = " + ".join(os.path.basename(x.rstrip("/")) for x in dirnames
                          if glob.glob(os.path.join(x, "truth_*.fits")))
        for label, prefix, cols in (("raw e", "fit", ["e1", "e2"]),
                                    ("calibrated (population)", "cal", ["e1_cal", "e2_cal"]),
                                    ("calibrated per object", "obj", ["e1_cal", "e2_cal"]),
                                    ("calibrated (population, table measured at this S/N)", "matched",
                                     ["e1_cal", "e2_cal"])):
            d = load(dirnames, prefix, cols)
            if d is None:
                continue
            rows = regress(d, *cols)
            (m1, sm1, c1, sc1, n, _), (m2, sm2, c2, sc2, *_) = rows
            m, sm = mean_slope(rows)
            print(f"| {name}, {label} | {m:+.2e} ± {sm:.1e} | {m1:+.2e} ± {sm1:.1e} | "
                  f"{m2:+.2e} ± {sm2:.1e} | {c1:+.2e} ± {sc1:.1e} | {c2:+.2e} ± {sc2:.1e} | {n} |")


if __name__ == "__main__":
    main()
