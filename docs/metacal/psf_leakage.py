"""Summarises docs/metacal/psf_leakage.sh: c per PSF (from each run's shear pair, c = (g+ + g-) / 2,
g = <R>^-1 <e> over usable objects) and alpha_i = (c_i(+A) - c_i(-A)) / 2A, with errors from a
bootstrap over the noise-pair groups (objects 4q .. 4q+3), one resample shared by every run and
both sets of a pair, so the galaxies and noise the runs share cancel in the differences.

    psf_leakage.py OUTDIR A   (needs `import stampede`: PYTHONPATH=build/python)
"""
import sys

import numpy as np

import stampede

RUNS = ("p1", "m1", "p2", "m2")
BOOTSTRAP = 400


def unit_sums(path):
    """Per noise-pair group: the sums of e1, e2, R11, R12, R21, R22 over its usable objects."""
    t = stampede.read_results(path)
    usable = (t["status"] == 0) & ((t["flags"] & stampede.shear_excluding_flags) == 0)
    for c in ("e1", "e2", "R11", "R12", "R21", "R22"):
        usable &= np.isfinite(t[c])
    unit = t["id"] // 4
    n = int(unit.max()) + 1
    return np.array([np.bincount(unit, weights=np.where(usable, t[c], 0.0), minlength=n)
                     for c in ("e1", "e2", "R11", "R12", "R21", "R22")]), int(usable.sum())


def shear(sums, w):
    e1, e2, a, b, c, d = (sums * w).sum(axis=1)
    det = a * d - b * c
    return np.array([(d * e1 - b * e2) / det, (-c * e1 + a * e2) / det])


def main(out, amplitude):
    data = {r: [unit_sums(f"{out}/{r}/fit_{k}.fits") for k in (0, 1)] for r in RUNS}
    units = data["p1"][0][0].shape[1]
    rng = np.random.default_rng(1)

    def estimate(w):
        c = {r: 0.5 * (shear(data[r][0][0], w) + shear(data[r][1][0], w)) for r in RUNS}
        alpha = np.array([(c["p1"][0] - c["m1"][0]) / (2 * amplitude), (c["p2"][1] - c["m2"][1]) / (2 * amplitude)])
        return c, alpha

    c0, a0 = estimate(np.ones(units))
    boots = [estimate(np.bincount(rng.integers(0, units, units), minlength=units)) for _ in range(BOOTSTRAP)]
    c_err = {r: np.std([b[0][r] for b in boots], axis=0) for r in RUNS}
    a_err = np.std([b[1] for b in boots], axis=0)
    psf = {"p1": (amplitude, 0), "m1": (-amplitude, 0), "p2": (0, amplitude), "m2": (0, -amplitude)}
    print(f"Shear pairs, {units} noise-pair groups of 4 objects per set; bootstrap over groups ({BOOTSTRAP}).\n")
    print("| PSF e | objects used (both sets) | c1 | c2 |")
    print("|---|---|---|---|")
    for r in RUNS:
        used = data[r][0][1] + data[r][1][1]
        print(f"| ({psf[r][0]:+.2f}, {psf[r][1]:+.2f}) | {used} | {c0[r][0]:+.2e} ± {c_err[r][0]:.1e} | "
              f"{c0[r][1]:+.2e} ± {c_err[r][1]:.1e} |")
    print(f"\nalpha1 = {a0[0]:+.2e} ± {a_err[0]:.1e}   alpha2 = {a0[1]:+.2e} ± {a_err[1]:.1e}")


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]))
