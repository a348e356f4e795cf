"""Analysis of docs/multiband/snr20.sh's sets.

Errors: per object usable in both fits (status ok, none of the shear-excluding flags), the ratio of
the joint fit's e errors to the g band's alone, against the ratio the summed S/N^2 predicts,
snr(g alone) / snr(joint) (snr the model's sqrt(sum w m^2): the joint one sums all bands' S/N^2).
Shear: per pair (+g, -g on the same galaxies and noise), m per component from the least-squares
slope of the pairs' half differences of <e> on the applied shear, c from the half sums; errors by a
bootstrap over objects, resampling both sets of a pair alike.

    python3 docs/multiband/snr20.py OUTDIR SHEARS
"""
import sys

import numpy as np
import stampede

EXCLUDING = int(stampede.shear_excluding_flags)
COLS = ["e1", "e2", "e1_err", "e2_err", "snr", "flags", "status"]


def table(path):
    t = stampede.read_table(path, "RESULTS", COLS)
    return {k: np.asarray(v, dtype=float) for k, v in t.items()}


def usable(t):
    return (t["status"] == 0) & ((t["flags"].astype(np.int64) & EXCLUDING) == 0)


def shear(sets, rng):
    def m_and_c(resample):
        num, den, cs = np.zeros(2), np.zeros(2), []
        for g, p, m, idx in sets:
            sel = rng.choice(idx, len(idx)) if resample else idx
            ep = np.array([p["e1"][sel].mean(), p["e2"][sel].mean()])
            em = np.array([m["e1"][sel].mean(), m["e2"][sel].mean()])
            num += g * (0.5 * (ep - em) - g)
            den += g * g
            cs.append(0.5 * (ep + em))
        return num / den, np.mean(cs, axis=0)

    m, c = m_and_c(False)
    boot = [m_and_c(True) for _ in range(300)]
    return m, np.std([b[0] for b in boot], axis=0), c, np.std([b[1] for b in boot], axis=0)


def main():
    out, shears = sys.argv[1], [np.array([float(x) for x in s.split(",")]) for s in sys.argv[2].split()]
    rng = np.random.default_rng(3)
    ratio1, ratio2, predicted = [], [], []
    sets = {"joint": [], "g_only": []}
    for k, g in enumerate(shears):
        t = {(kind, sign): table(f"{out}/set{k}{sign}/{kind}.fits") for kind in sets for sign in "pm"}
        ok = np.ones(len(t["joint", "p"]["e1"]), bool)
        for v in t.values():
            ok &= usable(v)
        idx = np.flatnonzero(ok)
        for kind in sets:
            sets[kind].append((g, t[kind, "p"], t[kind, "m"], idx))
        for sign in "pm":
            j, one = t["joint", sign], t["g_only", sign]
            ratio1.append(j["e1_err"][idx] / one["e1_err"][idx])
            ratio2.append(j["e2_err"][idx] / one["e2_err"][idx])
            predicted.append(one["snr"][idx] / j["snr"][idx])
    r1, r2, pr = np.concatenate(ratio1), np.concatenate(ratio2), np.concatenate(predicted)
    n = sum(len(s[3]) for s in sets["joint"])
    print(f"{len(shears)} shear pairs, {n} objects usable in all four fits of their pair")
    print(f"e errors, joint / g alone: median e1 {np.median(r1):.4f}, e2 {np.median(r2):.4f}; predicted by the summed "
          f"S/N^2, snr(g) / snr(joint): median {np.median(pr):.4f} (1/sqrt(3) = {1 / np.sqrt(3):.4f})")
    print(f"  measured / predicted: e1 {np.median(r1) / np.median(pr):.4f}, e2 {np.median(r2) / np.median(pr):.4f}; "
          f"per object median of (ratio / prediction) e1 {np.median(r1 / pr):.4f}, e2 {np.median(r2 / pr):.4f}")
    for kind in sets:
        m, sm, c, sc = shear(sets[kind], rng)
        print(f"{kind}: m1 = {m[0]:+.2e} +- {sm[0]:.1e}   m2 = {m[1]:+.2e} +- {sm[1]:.1e}   "
              f"c1 = {c[0]:+.2e} +- {sc[0]:.1e}   c2 = {c[1]:+.2e} +- {sc[1]:.1e}")


main()
