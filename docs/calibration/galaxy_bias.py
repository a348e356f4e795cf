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
replacement for the shear-based m. Rows excluded as in `stampede metrics` (status, flags), with
their noise partner.
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
        rows.append((coef[1], cov[1, 1] ** 0.5, coef[0], cov[0, 0] ** 0.5, len(x)))
    return rows


def main():
    print("| S/N dir, catalogue | m_gal,1 | m_gal,2 | c_gal,1 | c_gal,2 | noise pairs |")
    print("|---|---|---|---|---|---|")
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
            (m1, sm1, c1, sc1, n), (m2, sm2, c2, sc2, _) = regress(d, *cols)
            print(f"| {name}, {label} | {m1:+.2e} ± {sm1:.1e} | "
                  f"{m2:+.2e} ± {sm2:.1e} | {c1:+.2e} ± {sc1:.1e} | {c2:+.2e} ± {sc2:.1e} | {n} |")


if __name__ == "__main__":
    main()
