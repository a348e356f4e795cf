#!/usr/bin/env python3
"""Checks galaxy_bias.py's shear-response estimator m_resp on synthetic biases of known response.

usage: check_shear_response.py [GALAXIES]   (default 2,000,000; ~20 s)

Galaxies are drawn as `sim great08` draws them (each component N(0, ESIG), redrawn until
|e| < EMAX, ring pairs, sets sheared by g uniform in |g_i| < 0.05), given a bias b(e) with no noise,
and passed through galaxy_bias.regress as the experiment's catalogues are. The true response of
<e + b> is measured by shearing the same intrinsic shapes by +-h (common random numbers). Prints
both, and m_gal beside them.
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from galaxy_bias import mean_slope, regress  # noqa: E402

SIGMA, E_MAX, SHEAR_MAX, SETS = 0.25, 0.9, 0.05, 14


def draw(rng, n):
    e = rng.normal(0, SIGMA, n) + 1j * rng.normal(0, SIGMA, n)
    while (bad := np.abs(e) >= E_MAX).any():
        e[bad] = rng.normal(0, SIGMA, bad.sum()) + 1j * rng.normal(0, SIGMA, bad.sum())
    return e


def shear(e, g):
    return (e + g) / (1 + np.conj(g) * e)


BIASES = {  # name: b(e), complex
    "radial a1 = 0.06, a3 = -0.15": lambda e: (0.06 - 0.15 * abs(e) ** 2) * e,
    "radial a1 = 0.06, a3 = -0.15, c = -3e-3 i (1 + 2|e|^2)": lambda e: (0.06 - 0.15 * abs(e) ** 2) * e
    - 3e-3j * (1 + 2 * abs(e) ** 2),
    "radial a1 = 0.02, a3 = +0.10, a5 = -0.2": lambda e: (0.02 + 0.1 * abs(e) ** 2 - 0.2 * abs(e) ** 4) * e,
    "anisotropic: 0.05 e + 0.02 e1 (|e|^2 along e1 only)": lambda e: 0.05 * e + 0.02 * e.real * abs(e) ** 2,
}


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 2_000_000
    rng = np.random.default_rng(44)
    intrinsic = draw(rng, n)
    per_set = n // SETS // 4 * 4  # rows of a set; its quads take per_set / 4 intrinsic shapes
    print("| bias | true m1 | m_resp,1 | true m2 | m_resp,2 | true m | m_resp | m_gal |")
    print("|---|---|---|---|---|---|---|---|")
    shears = rng.uniform(-SHEAR_MAX, SHEAR_MAX, (SETS, 2))
    bases = [intrinsic[k * per_set // 4:(k + 1) * per_set // 4] for k in range(SETS)]
    # The galaxies the regression sees: per set, quads of ring pairs whose noise pairs are identical.
    e_true = np.concatenate([shear(np.stack([x, -x, x, -x], axis=1).ravel(), g1 + 1j * g2)
                             for x, (g1, g2) in zip(bases, shears)])
    unsheared = np.concatenate(bases + [-x for x in bases])
    for name, b in BIASES.items():
        h = 1e-3
        true = []
        for g in (h, 1j * h):  # the same shapes (ring pairs included) sheared by +-h
            up, down = shear(unsheared, g), shear(unsheared, -g)
            diff = np.mean(up + b(up) - down - b(down)) / (2 * h)
            true.append((diff.real if g.real else diff.imag) - 1)
        e_obs = e_true + b(e_true)
        d = {"e1": e_obs.real, "e2": e_obs.imag, "e1_true": e_true.real, "e2_true": e_true.imag,
             "ok": np.ones(len(e_true), bool), "sigma": SIGMA}
        resp = regress(d, "e1", "e2", response=True)
        m_resp, _ = mean_slope(resp)
        m_gal, _ = mean_slope(regress(d, "e1", "e2", response=False))
        print(f"| {name} | {true[0]:+.5f} | {resp[0][0]:+.5f} | {true[1]:+.5f} | {resp[1][0]:+.5f} | "
              f"{np.mean(true):+.5f} | {m_resp:+.5f} | {m_gal:+.5f} |")


if __name__ == "__main__":
    main()
