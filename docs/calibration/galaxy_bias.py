#!/usr/bin/env python3
"""Per-galaxy bias of the experiment's catalogues against the simulation truth.

usage: galaxy_bias.py DIRS [DIRS ...]   (DIRS: an S/N directory of run_experiment.sh, or several
                                        joined by commas, pooled: an S/N and its extra batches)

`stampede metrics` measures m from the set means against the sets' shears: with 8 sets whose
shears spread over |g| < 0.05, its error on m is ~1e-2 at S/N 20. The truth files give each
galaxy's sheared ellipticity e_true, whose spread (~0.25) is a far longer lever arm: here the
noise-pair means b of e - e_true (objects 4q+r and 4q+r+2 of a set share the galaxy and have
opposite noise) are regressed on e_true per component over all sets, for the raw e and the
calibrated e1_cal, e2_cal, two ways:

- m_resp, the shear response: d<b_1>/dg_1 = <b_1 S_1> with S_1 = d ln p/dg_1 the score of the
  intrinsic distribution under the lensing of e (e -> e + g - e^2 g*). For the simulation's
  Gaussian of sigma ESIG per component, S_1 = e_1 (1 + 4 sigma^2 - |e|^2) / sigma^2, so m_resp is
  the regression b_1 = c + m e_1 weighted by w = 1 + 4 sigma^2 - |e_true|^2. This is the m of the
  shear estimate (what `stampede metrics` measures from the sets and what the calibration's
  m = a1 + 2 a3 r^2 - a3 r^4 removes), to ~1e-4 for the truncation at EMAX and set shears of 0.05
  (checked on synthetic biases by check_shear_response.py);
- m_gal, the unweighted regression: for b = a1 e + a3 e^3 along the radius it gives
  a1 + a3 <r^4>/<r^2>, which differs from the response by -a3 <r^4> (a3 ~ -0.1 at S/N 20: 3e-3):
  kept for the history tables, which quote it.

m = (m_1 + m_2) / 2 with its error from both components' residuals per noise pair together. Rows
excluded as in `stampede metrics` (status, flags), with their noise partner; each set is read to
a multiple of 4 rows (an odd grid's last object has no noise partner). The regression takes every
set as independent: on shear-pair sets, whose two members repeat the same galaxies and noise, its
errors are too small.

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
    """Rows of every set with its truth, each set cut to a multiple of 4 so that quads stay aligned."""
    out = {c: [] for c in cols + ["e1_true", "e2_true", "ok"]}
    sigmas = set()
    truths = [t for dirname in dirnames for t in sorted(glob.glob(os.path.join(dirname, "truth_*.fits")))]
    for truth in truths:
        dirname = os.path.dirname(truth)
        k = truth.rsplit("_", 1)[1][:-5]
        path = os.path.join(dirname, f"{prefix}_{k}.fits")
        if not os.path.exists(path):
            continue
        t = fits.open(path)[1].data
        with fits.open(truth) as h:
            tr = h[1].data
            sigmas.add(float(h[0].header["ESIG"]))
        if len(t) != len(tr):
            sys.exit(f"{path}: {len(t)} rows, its truth {truth} {len(tr)}")
        n = len(t) // 4 * 4
        ok = (t["status"] == 0) & ((t["flags"].astype(np.int64) & EXCLUDING) == 0)
        for c in cols:
            out[c].append(np.asarray(t[c], float)[:n])
        out["e1_true"].append(np.asarray(tr["e1_obs"], float)[:n])
        out["e2_true"].append(np.asarray(tr["e2_obs"], float)[:n])
        out["ok"].append((ok & np.isfinite(t[cols[0]]) & np.isfinite(t[cols[1]]))[:n])
    if not out["ok"]:
        return None
    if len(sigmas) != 1:
        sys.exit(f"{', '.join(dirnames)}: sets of different intrinsic e sigma (ESIG {sorted(sigmas)}): not one population")
    d = {c: np.concatenate(v) for c, v in out.items()}
    d["sigma"] = sigmas.pop()
    return d


def regress(d, e1, e2, response):
    """Per component (slope, its error, intercept, its error, pairs, each galaxy's share of the
    slope): the unweighted regression (m_gal) or, with response, the shear response (m_resp)."""
    truth = {c: d[f"e{c}_true"].reshape(-1, 4) for c in (1, 2)}
    ok = d["ok"].reshape(-1, 4)
    quads = len(ok)
    # The two noise pairs of a quad (r = 0, 1: a ring pair) side by side; an unusable pair weighs 0.
    pair_ok = np.concatenate([ok[:, r] & ok[:, r + 2] for r in (0, 1)])
    t = {c: np.concatenate([truth[c][:, r] for r in (0, 1)]) for c in (1, 2)}
    w = 1 + 4 * d["sigma"] ** 2 - (t[1] ** 2 + t[2] ** 2) if response else np.ones_like(t[1])
    w = np.where(pair_ok, w, 0.0)
    rows = []
    for comp, name in ((1, e1), (2, e2)):
        bias = (d[name] - d[f"e{comp}_true"]).reshape(-1, 4)
        y = np.where(pair_ok, np.concatenate([(bias[:, r] + bias[:, r + 2]) / 2 for r in (0, 1)]), 0.0)
        a = np.vstack([np.ones_like(t[comp]), t[comp]]).T
        normal = a.T @ (a * w[:, None])
        coef = np.linalg.solve(normal, a.T @ (w * y))
        residual = y - a @ coef
        # Each pair's share of the coefficients (the sandwich form, right for any weights), summed
        # per galaxy (a ring pair shares one) and kept for the error of (m1 + m2) / 2: both
        # components' regressions use the same galaxies.
        influence = np.linalg.solve(normal, (a * (w * residual)[:, None]).T)
        influence = influence[:, :quads] + influence[:, quads:]
        errors = np.sqrt(np.sum(influence ** 2, axis=1))
        rows.append((coef[1], errors[1], coef[0], errors[0], int(pair_ok.sum()), influence[1]))
    return rows


def mean_slope(rows):
    """m = (m_1 + m_2) / 2 and its error from both components' residuals together."""
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
    print("| S/N dir, catalogue | m_resp | m_resp,1 | m_resp,2 | m_gal | c_gal,1 | c_gal,2 | noise pairs |")
    print("|---|---|---|---|---|---|---|---|")
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
            rows = regress(d, *cols, response=True)
            (m1, sm1, *_), (m2, sm2, *_) = rows
            m, sm = mean_slope(rows)
            plain = regress(d, *cols, response=False)
            (_, _, c1, sc1, n, _), (_, _, c2, sc2, *_) = plain
            m_gal, sm_gal = mean_slope(plain)
            print(f"| {name}, {label} | {m:+.2e} ± {sm:.1e} | {m1:+.2e} ± {sm1:.1e} | "
                  f"{m2:+.2e} ± {sm2:.1e} | {m_gal:+.2e} ± {sm_gal:.1e} | {c1:+.2e} ± {sc1:.1e} | "
                  f"{c2:+.2e} ± {sc2:.1e} | {n} |")


if __name__ == "__main__":
    main()
