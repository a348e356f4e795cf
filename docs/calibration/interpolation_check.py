#!/usr/bin/env python3
"""How the calibration's interpolation between grid nodes changes m, checked on a dense table.

usage: interpolation_check.py DENSE.fits DEEP.fits [COARSE_RADII [COARSE_FRACTIONS]]
       (defaults 1.2,1.6,2.1,2.8 and 0,0.5,1: the fine-radii tables' grid, a subset of the dense one)

Needs numpy, scipy and astropy. For a population (the deep fits' r_d, F, |e|), a node's m is the
mean over the population's |e| of a1 + a3 |e|^2 (2 - |e|^2), the calibration's formula. Two checks:
1. the coarse subset of the dense table predicts the nodes it leaves out (those inside its radii),
   under each interpolation scheme: rms, largest and mean error against the held-out nodes' own m
   (which carry the table's noise, ~1e-3 a node at 400 pairs, a floor under every scheme);
2. the population m-hat from the whole dense table and from its coarse subset, per scheme (the
   deep rows clamped to each grid's edge as `calibrate apply` does).
The Gaussian RBF is the paper's (widths 0.9 in ln r_d and 0.5 in F, stampede's until issue 44);
"not-a-knot" is kernels/tensor_spline (three nodes: the parabola).
"""
import sys

import numpy as np
from astropy.io import fits
from scipy.interpolate import CubicSpline


def node_coefficients(path):
    c = fits.open(path)["CURVES"].data
    radii = np.array(sorted(set(c["radius"])))
    fractions = np.array(sorted(set(c["bulge_fraction"])))
    a1 = np.zeros((len(radii), len(fractions)))
    a3 = np.zeros_like(a1)
    for i, r in enumerate(radii):
        for j, f in enumerate(fractions):
            for axis, comp in ((0, 0), (1, 1)):  # b_11 along e1 and b_22 along e2, averaged
                row = c[(c["radius"] == r) & (c["bulge_fraction"] == f) & (c["axis"] == axis) & (c["component"] == comp)][0]
                a1[i, j] += row["a1"] / 2
                a3[i, j] += row["a3"] / 2
    return radii, fractions, a1, a3


def rbf_weights(x_nodes, y_nodes, q, length=(0.9, 0.5)):
    nodes = np.array([(a, b) for a in x_nodes for b in y_nodes])
    n = len(nodes)
    a = np.zeros((n + 3, n + 3))
    d = (nodes[:, None, :] - nodes[None, :, :]) / np.array(length)
    a[:n, :n] = np.exp(-0.5 * (d ** 2).sum(-1))
    a[:n, n] = a[n, :n] = 1
    a[:n, n + 1:] = nodes
    a[n + 1:, :n] = nodes.T
    if np.linalg.cond(a) > 1e13:
        return None  # stampede refused such a grid as singular
    dq = (q[:, None, :] - nodes[None, :, :]) / np.array(length)
    basis = np.hstack([np.exp(-0.5 * (dq ** 2).sum(-1)), np.ones((len(q), 1)), q])
    return basis @ np.linalg.inv(a)[:, :n]


def axis_weights(nodes, x, kind):
    if len(nodes) == 1:
        return np.ones((len(x), 1))
    unit = np.eye(len(nodes))
    if kind == "linear" or len(nodes) == 2:
        return np.stack([np.interp(x, nodes, unit[k]) for k in range(len(nodes))], axis=1)
    return np.stack([CubicSpline(nodes, unit[k], bc_type=kind)(x) for k in range(len(nodes))], axis=1)


def tensor_weights(x_nodes, y_nodes, q, kind):
    wx, wy = axis_weights(x_nodes, q[:, 0], kind), axis_weights(y_nodes, q[:, 1], kind)
    return (wx[:, :, None] * wy[:, None, :]).reshape(len(q), -1)


SCHEMES = {
    "Gaussian RBF 0.9 / 0.5 (the paper's)": lambda xn, yn, q: rbf_weights(xn, yn, q),
    "bilinear": lambda xn, yn, q: tensor_weights(xn, yn, q, "linear"),
    "natural cubic splines": lambda xn, yn, q: tensor_weights(xn, yn, q, "natural"),
    "not-a-knot cubic splines (stampede)": lambda xn, yn, q: tensor_weights(xn, yn, q, "not-a-knot"),
}


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    radii, fractions, a1, a3 = node_coefficients(sys.argv[1])
    coarse_r = [float(v) for v in (sys.argv[3] if len(sys.argv) > 3 else "1.2,1.6,2.1,2.8").split(",")]
    coarse_f = [float(v) for v in (sys.argv[4] if len(sys.argv) > 4 else "0,0.5,1").split(",")]
    ri = [i for i, r in enumerate(radii) if min(abs(r - c) for c in coarse_r) < 1e-9]
    fi = [j for j, f in enumerate(fractions) if min(abs(f - c) for c in coarse_f) < 1e-9]
    if len(ri) != len(coarse_r) or len(fi) != len(coarse_f):
        sys.exit(f"{sys.argv[1]}: the coarse grid {coarse_r} x {coarse_f} is not a subset of its nodes")
    deep = fits.open(sys.argv[2])[1].data
    usable = (deep["status"] == 0) & np.isfinite(deep["radius"])
    deep = deep[usable]
    e = np.minimum(np.hypot(deep["e1"], deep["e2"]), 0.8)
    shape = e * e * (2 - e * e)
    node_m = a1 + a3 * shape.mean()

    held = [(i, j) for i in range(len(radii)) for j in range(len(fractions))
            if (i not in ri or j not in fi) and radii[ri[0]] <= radii[i] <= radii[ri[-1]]]
    q = np.array([(np.log(radii[i]), fractions[j]) for i, j in held])
    truth = np.array([node_m[i, j] for i, j in held])
    print(f"1. {len(held)} held-out nodes of {sys.argv[1]} predicted from its {len(ri)} x {len(fi)} subset:")
    print()
    print("| scheme | rms error | largest | mean |")
    print("|---|---|---|---|")
    for name, weights in SCHEMES.items():
        w = weights(np.log(radii[ri]), fractions[fi], q)
        d = w @ node_m[np.ix_(ri, fi)].ravel() - truth
        print(f"| {name} | {np.sqrt(np.mean(d * d)):.2e} | {np.abs(d).max():.2e} | {d.mean():+.2e} |")
    print()
    fraction = np.clip(deep["bulge_flux"] / (deep["bulge_flux"] + deep["disc_flux"]), 0, 1)
    print(f"2. population m-hat over the {len(deep)} deep rows of {sys.argv[2]}:")
    print()
    print(f"| scheme | dense ({len(radii)} x {len(fractions)}) | coarse subset ({len(ri)} x {len(fi)}) |")
    print("|---|---|---|")
    for name, weights in SCHEMES.items():
        row = []
        for rs, fs in ((list(range(len(radii))), list(range(len(fractions)))), (ri, fi)):
            lr = np.clip(np.log(deep["radius"]), np.log(radii[rs[0]]), np.log(radii[rs[-1]]))
            ff = np.clip(fraction, fractions[fs[0]], fractions[fs[-1]])
            w = weights(np.log(radii[rs]), fractions[fs], np.stack([lr, ff], 1))
            row.append("singular" if w is None else
                       f"{np.mean(w @ a1[np.ix_(rs, fs)].ravel() + (w @ a3[np.ix_(rs, fs)].ravel()) * shape):.5f}")
        print(f"| {name} | {row[0]} | {row[1]} |")


if __name__ == "__main__":
    main()
