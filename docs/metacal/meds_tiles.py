"""Shear-pair analysis of docs/metacal/meds_tiles.sh's sets: per pair (+g, -g on the same galaxies
and noise) g = <R>^-1 (<e+> - <e->) / 2 over the objects usable in both (status ok, none of the
shear-excluding flags), <R> the mean over both sets; m per component the least-squares slope of the pairs' g
on the applied, less 1, c from the half sums; errors by a bootstrap over objects, resampling
both sets of a pair alike.

With CUT (arcsec), objects are kept where radius >= CUT in each set on its own, and the selection
response R_S (Sheldon & Huff 2017) from the sheared images' radii joins <R>:
R_S,ij = (<e_i>[radius_jp >= CUT] - <e_i>[radius_jm >= CUT]) / (2 step).

    python3 docs/metacal/meds_tiles.py OUTDIR SHEARS [CUT]   (SHEARS as meds_tiles.sh's, e.g. "0.02,-0.015 0.0,0.02")

FIT (environment) names each set's table: fit.fits (meds_tiles.sh's), or e.g. joint_metacal.fits for
docs/multiband/snr20.sh's metacal across bands.
"""
import os
import sys

import numpy as np
import stampede

EXCLUDING = int(stampede.shear_excluding_flags)
COLS = ["e1", "e2", "R11", "R12", "R21", "R22", "flags", "status", "radius", "radius_1p", "radius_1m", "radius_2p",
        "radius_2m"]
STEP = 0.01


def table(path):
    t = stampede.read_table(path, "RESULTS", COLS)
    return {k: np.asarray(v, dtype=float) for k, v in t.items()}


def estimate(p, m, idx, cut):
    rp, ep, _ = selected(p, idx, cut)
    rm, em, _ = selected(m, idx, cut)
    r = 0.5 * (rp + rm)
    return np.linalg.solve(r, 0.5 * (ep - em)), np.linalg.solve(r, 0.5 * (ep + em))


def selected(t, idx, cut):
    """<R> + R_S and <e> over the objects of idx kept by the cut (all of idx without one)."""
    keep = idx if cut is None else idx[t["radius"][idx] >= cut]
    r = np.array([[t["R11"][keep].mean(), t["R12"][keep].mean()], [t["R21"][keep].mean(), t["R22"][keep].mean()]])
    if cut is not None:
        for j, (plus, minus) in enumerate((("radius_1p", "radius_1m"), ("radius_2p", "radius_2m"))):
            sp, sm = idx[t[plus][idx] >= cut], idx[t[minus][idx] >= cut]
            for i, e in enumerate(("e1", "e2")):
                r[i, j] += (t[e][sp].mean() - t[e][sm].mean()) / (2 * STEP)
    return r, np.array([t["e1"][keep].mean(), t["e2"][keep].mean()]), len(keep)


def main():
    out, shears = sys.argv[1], [tuple(float(x) for x in s.split(",")) for s in sys.argv[2].split()]
    cut = float(sys.argv[3]) if len(sys.argv) > 3 else None
    rng = np.random.default_rng(1)
    pairs = []
    for k, g in enumerate(shears):
        name = os.environ.get("FIT", "fit.fits")
        p, m = table(f"{out}/set{k}p/{name}"), table(f"{out}/set{k}m/{name}")
        ok = np.ones(len(p["e1"]), bool)
        for t in (p, m):
            ok &= (t["status"] == 0) & ((t["flags"].astype(np.int64) & EXCLUDING) == 0)
        pairs.append((np.array(g), p, m, np.flatnonzero(ok), len(ok)))

    def m_and_c(resample):
        num, den, cs = np.zeros(2), np.zeros(2), []
        for g, p, m, idx, _ in pairs:
            sel = rng.choice(idx, len(idx)) if resample else idx
            diff, half_sum = estimate(p, m, sel, cut)
            num += g * (diff - g)
            den += g * g
            cs.append(half_sum)
        return num / den, np.mean(cs, axis=0)

    m, c = m_and_c(False)
    boot = [m_and_c(True) for _ in range(200)]
    sm = np.std([b[0] for b in boot], axis=0)
    sc = np.std([b[1] for b in boot], axis=0)
    used = sum(len(x[3]) for x in pairs)
    total = sum(x[4] for x in pairs)
    kept = sum(selected(t, x[3], cut)[2] for x in pairs for t in (x[1], x[2]))
    print(f"pairs {len(pairs)}, objects usable in both sets of a pair: {used} of {total}"
          + ("" if cut is None else f"; kept by radius >= {cut}\": {kept} of {2 * used}"))
    print(f"m1 = {m[0]:+.2e} +- {sm[0]:.1e}   m2 = {m[1]:+.2e} +- {sm[1]:.1e}")
    print(f"c1 = {c[0]:+.2e} +- {sc[0]:.1e}   c2 = {c[1]:+.2e} +- {sc[1]:.1e}")


if __name__ == "__main__":
    main()
