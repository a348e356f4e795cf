#!/usr/bin/env python3
"""The metadetection shear test, run in chunks that survive across sessions (docs/metadetect.md,
"The reference shear test").

Each chunk simulates CHUNK shear pairs with `stampede sim cells --pair` (its own seed, so chunks are
independent), measures both signs with `stampede metadetect`, and keeps only each cell's sums per
shear type after the cuts (n, sum e1, sum e2: 30 numbers a pair) in RESULTS/LABEL/chunk_KKKKK.txt;
the images are deleted. A chunk whose file exists is not run again, so an interrupted or extended
test goes on where it stopped. The summary reads every chunk file and prints, for the reference
package's estimator (per cell and shear type the mean e of the kept rows; over cells
m = <g1+ - g1->/2 / <R11+ + R11->/2 / g - 1, c = <g2+ + g2->/2 / <R22+ + R22->/2) and for the pooled
one of `stampede metrics --metadetect` (every cell's kept rows summed first): R11, m, c with
bootstrap errors over pairs, and sigma_m per pair (sigma_m x sqrt(pairs)); and m from the pooled
means to second order in the shear (the catalogues' curvature (e_1p + e_1m - 2 e_noshear) / step^2
removes the estimator's O(g^2) term; docs/metadetect.md, "The grid's bias"), and the pooled one
with the response divided by 1 - |g|^2, metacal's step composed with the image's shear
("composed").

usage: shear_test.py --label L --pairs N [--chunk 100] [--build build] [--work /tmp/shear_test]
           [--results docs/metadetect/results] [--sim "sim cells options"]
           [--metadetect "metadetect options"] [--cut-snr 10] [--cut-t-ratio 1.2] [--summary-only]
           [--compare OTHER_LABEL]
e.g.  shear_test.py --label ref_grid --pairs 200 --sim="--reference --layout grid" --metadetect="--recentre"
(options' values that begin with "--" are given with "=")
"""
import argparse
import gzip
import os
import shlex
import shutil
import subprocess
import sys
import time

import numpy as np

TYPES = 5  # noshear 1p 1m 2p 2m, as the table's shear_type


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def cell_sums(path, cells, cut_snr, cut_t_ratio, read_table):
    """(cells, 5, 3) array of n, sum e1, sum e2 of the rows kept by the reference test's cuts."""
    cols = read_table(path, 1, ["cell", "shear_type", "e1", "e2", "snr", "T_ratio", "flags"])
    cols = {k: np.asarray(v) for k, v in cols.items()}
    keep = (cols["flags"] == 0) & (cols["snr"] > cut_snr) & (cols["T_ratio"] > cut_t_ratio)
    out = np.zeros((cells, TYPES, 3))
    names = {"noshear": 0, "1p": 1, "1m": 2, "2p": 3, "2m": 4}
    types = np.array([names[str(x).strip()] for x in cols["shear_type"]], dtype=int)
    c, t = cols["cell"][keep].astype(int), types[keep]
    np.add.at(out, (c, t, 0), 1.0)
    np.add.at(out, (c, t, 1), cols["e1"][keep])
    np.add.at(out, (c, t, 2), cols["e2"][keep])
    return out


def run_chunk(a, k, path):
    import stampede  # noqa: the build's module (PYTHONPATH set below)
    stampede_bin = os.path.join(a.build, "tools", "stampede")
    work = os.path.join(a.work, a.label, "chunk_%05d" % k)
    shutil.rmtree(work, ignore_errors=True)
    seed = a.seed + k
    t0 = time.time()
    run([stampede_bin, "sim", "cells", "--out", work, "--cells", str(a.chunk), "--pair", "--seed", str(seed)] +
        shlex.split(a.sim))
    t1 = time.time()
    sums = []
    for sign, sub in (("plus", ""), ("minus", "minus")):
        d = os.path.join(work, sub)
        files = sorted(os.path.join(d, f) for f in os.listdir(d) if f.startswith("cell_") and f.endswith(".fits"))
        listing = os.path.join(work, sign + ".list")
        with open(listing, "w") as f:
            f.write("\n".join(files) + "\n")
        table = os.path.join(work, sign + "_table.fits")
        run([stampede_bin, "metadetect", "--input-list", listing, "-o", table, "--quiet"] + shlex.split(a.metadetect))
        sums.append(cell_sums(table, a.chunk, a.cut_snr, a.cut_t_ratio, stampede.read_table))
    t2 = time.time()
    rows = np.concatenate([sums[0].reshape(a.chunk, -1), sums[1].reshape(a.chunk, -1)], axis=1)
    tmp = path + ".tmp.gz"
    header = ("seed %d; sim: %s; metadetect: %s; cuts snr > %g t_ratio > %g; simulate %.1f s measure %.1f s\n"
              "per pair: plus then minus, each shear type (noshear 1p 1m 2p 2m) n sum_e1 sum_e2"
              % (seed, a.sim, a.metadetect, a.cut_snr, a.cut_t_ratio, t1 - t0, t2 - t1))
    np.savetxt(tmp, rows, fmt="%.10g", header=header)
    os.replace(tmp, path)
    shutil.rmtree(work, ignore_errors=True)
    return t1 - t0, t2 - t1


def estimates(plus, minus, g, step):
    """Both estimators on arrays (pairs, 5, 3): returns dict of name -> (m, c, R11)."""
    out = {}
    # Reference: per-cell means per shear type.
    def cell_means(s):
        with np.errstate(invalid="ignore", divide="ignore"):
            return s[:, :, 1] / s[:, :, 0], s[:, :, 2] / s[:, :, 0]
    e1p, e2p = cell_means(plus)
    e1m, e2m = cell_means(minus)
    r11p, r11m = (e1p[:, 1] - e1p[:, 2]) / (2 * step), (e1m[:, 1] - e1m[:, 2]) / (2 * step)
    r22p, r22m = (e2p[:, 3] - e2p[:, 4]) / (2 * step), (e2m[:, 3] - e2m[:, 4]) / (2 * step)
    ok = np.isfinite(r11p + r11m + r22p + r22m + e1p[:, 0] + e1m[:, 0])
    r11 = np.mean(r11p[ok] + r11m[ok]) / 2
    m = np.mean(e1p[ok, 0] - e1m[ok, 0]) / 2 / r11 / g - 1
    c = np.mean(e2p[ok, 0] + e2m[ok, 0]) / 2 / (np.mean(r22p[ok] + r22m[ok]) / 2)
    out["reference"] = (m, c, r11)
    # Pooled: sums over cells first.
    P, M = plus.sum(axis=0), minus.sum(axis=0)
    mean = lambda S, t, i: S[t, i] / S[t, 0]
    r11p, r11m = (mean(P, 1, 1) - mean(P, 2, 1)) / (2 * step), (mean(M, 1, 1) - mean(M, 2, 1)) / (2 * step)
    r22p, r22m = (mean(P, 3, 2) - mean(P, 4, 2)) / (2 * step), (mean(M, 3, 2) - mean(M, 4, 2)) / (2 * step)
    r11 = (r11p + r11m) / 2
    m = (mean(P, 0, 1) - mean(M, 0, 1)) / 2 / r11 / g - 1
    c = (mean(P, 0, 2) + mean(M, 0, 2)) / 2 / ((r22p + r22m) / 2)
    out["pooled"] = (m, c, r11)
    # Second order (pooled sums): the response R = (e_1p - e_1m) / 2 step and the curvature
    # C = (e_1p + e_1m - 2 e_noshear) / step^2 of the catalogue means; for an odd mean response
    # E(s) = a s + b s^3 to the total shear s, with metacal's step composed with the shear g
    # (s = (g + d) / (1 + g d)), e = g R / (1 - g^2) - g^2 (C + 2 g R) / (3 (1 - g^2)^2): solved for g.
    def second_order(S):
        e, ep, em = mean(S, 0, 1), mean(S, 1, 1), mean(S, 2, 1)
        r, curv = (ep - em) / (2 * step), (ep + em - 2 * e) / step ** 2
        g = e / r
        for _ in range(50):
            g = (e + g * g * (curv + 2 * g * r) / (3 * (1 - g * g) ** 2)) * (1 - g * g) / r
        return g
    # Composed: metacal's step composes with the shear already in the image, (g + d) / (1 + g* d),
    # whose derivative in d is 1 - |g|^2: the response to the sky's shear is R / (1 - |g|^2).
    def composed(S):
        e, r = mean(S, 0, 1), (mean(S, 1, 1) - mean(S, 2, 1)) / (2 * step)
        e2, r2 = mean(S, 0, 2), (mean(S, 3, 2) - mean(S, 4, 2)) / (2 * step)
        g1, g2 = e / r, e2 / r2
        for _ in range(20):
            k = 1 - g1 * g1 - g2 * g2
            g1, g2 = e * k / r, e2 * k / r2
        return g1, g2
    (p1, p2), (m1_, m2_) = composed(P), composed(M)
    out["composed"] = ((p1 - m1_) / 2 / g - 1, (p2 + m2_) / 2, out["pooled"][2])
    gp, gm = second_order(P), second_order(M)
    out["2nd-order"] = ((gp - gm) / 2 / g - 1, out["pooled"][1], out["pooled"][2])
    return out


def settings(path):
    """The chunk's first header line without its seed and timings: what must agree across chunks."""
    with (gzip.open(path, "rt") if path.endswith(".gz") else open(path)) as f:
        line = f.readline()
    return line.split(";", 1)[1].rsplit(";", 1)[0].strip()


def summary(a, files):
    kinds = {settings(f) for f in files}
    if len(kinds) != 1:
        sys.exit("%s: chunk files of different settings: %s" % (a.label, " | ".join(sorted(kinds))))
    data = np.concatenate([np.atleast_2d(np.loadtxt(f)) for f in files])
    n = data.shape[0]
    plus = data[:, :15].reshape(n, TYPES, 3)
    minus = data[:, 15:].reshape(n, TYPES, 3)
    best = estimates(plus, minus, a.g, a.step)
    rng = np.random.default_rng(1)
    boot = {k: [] for k in best}
    for _ in range(a.bootstrap):
        i = rng.integers(0, n, n)
        for k, v in estimates(plus[i], minus[i], a.g, a.step).items():
            boot[k].append(v)
    print("%s: %d pairs (%d chunk files); %s" % (a.label, n, len(files), kinds.pop()))
    print("  detections kept per cell (noshear, +g): %.2f" % plus[:, 0, 0].mean())
    for k, (m, c, r11) in best.items():
        b = np.array(boot[k])
        sm, sc, sr = b[:, 0].std(), b[:, 1].std(), b[:, 2].std()
        print("  %-9s R11 %.4f +- %.4f  m %+.3e +- %.3e  c %+.3e +- %.3e  sigma_m per pair %.4f" %
              (k, r11, sr, m, sm, c, sc, sm * np.sqrt(n)))


def is_chunk(name):
    return name.startswith("chunk_") and (name.endswith(".txt") or name.endswith(".txt.gz"))


def load(results, label):
    out = os.path.join(results, label)
    files = sorted(f for f in os.listdir(out) if is_chunk(f))
    return {f.split(".")[0]: np.atleast_2d(np.loadtxt(os.path.join(out, f))) for f in files}


def compare(a, other):
    """m of this label minus m of `other` on the chunks both hold (the same seeds: the same cells),
    bootstrapped over pairs together, for the package's and the composed estimator."""
    mine, theirs = load(a.results, a.label), load(a.results, other)
    common = sorted(set(mine) & set(theirs))
    if not common:
        sys.exit("%s and %s share no chunk" % (a.label, other))
    x = np.concatenate([mine[f] for f in common])
    y = np.concatenate([theirs[f] for f in common])
    n = x.shape[0]
    split = lambda d, i: (d[i, :15].reshape(len(i), TYPES, 3), d[i, 15:].reshape(len(i), TYPES, 3))
    idx = np.arange(n)
    best = {k: v[0] - w[0] for (k, v), w in zip(estimates(*split(x, idx), a.g, a.step).items(),
                                                estimates(*split(y, idx), a.g, a.step).values())}
    rng = np.random.default_rng(2)
    boot = {k: [] for k in best}
    for _ in range(a.bootstrap):
        i = rng.integers(0, n, n)
        for (k, v), w in zip(estimates(*split(x, i), a.g, a.step).items(), estimates(*split(y, i), a.g, a.step).values()):
            boot[k].append(v[0] - w[0])
    print("%s - %s on %d common pairs (%d chunks):" % (a.label, other, n, len(common)))
    for k in ("reference", "composed"):
        print("  %-9s delta m %+.3e +- %.3e" % (k, best[k], np.std(boot[k])))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--label", required=True)
    p.add_argument("--pairs", type=int, default=0, help="pairs wanted in all (chunks are added up to it)")
    p.add_argument("--chunk", type=int, default=100)
    p.add_argument("--build", default="build")
    p.add_argument("--work", default="/tmp/shear_test")
    p.add_argument("--results", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    p.add_argument("--sim", default="--reference --layout grid")
    p.add_argument("--metadetect", default="")
    p.add_argument("--cut-snr", type=float, default=10)
    p.add_argument("--cut-t-ratio", type=float, default=1.2)
    p.add_argument("--seed", type=int, default=1000)
    p.add_argument("--g", type=float, default=0.02, help="the simulated shear g1 (sim cells' default)")
    p.add_argument("--step", type=float, default=0.01)
    p.add_argument("--bootstrap", type=int, default=500)
    p.add_argument("--summary-only", action="store_true")
    p.add_argument("--compare", metavar="LABEL", help="also m minus LABEL's m on the chunks both hold")
    a = p.parse_args()
    sys.path.insert(0, os.path.join(os.path.abspath(a.build), "python"))
    out = os.path.join(a.results, a.label)
    os.makedirs(out, exist_ok=True)
    chunks = (a.pairs + a.chunk - 1) // a.chunk
    if not a.summary_only:
        for k in range(chunks):
            path = os.path.join(out, "chunk_%05d.txt.gz" % k)
            if os.path.exists(path) or os.path.exists(path[:-3]):
                continue
            ts, tm = run_chunk(a, k, path)
            print("%s: chunk %d/%d done (simulate %.1f s, measure %.1f s)" % (a.label, k + 1, chunks, ts, tm),
                  flush=True)
    files = sorted(os.path.join(out, f) for f in os.listdir(out) if is_chunk(f))
    if files:
        summary(a, files)
    if a.compare:
        compare(a, a.compare)


if __name__ == "__main__":
    main()
